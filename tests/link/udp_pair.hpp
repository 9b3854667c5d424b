// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <memory>
#include <string>

#include "fnmpc/link/udp_transport.hpp"

/// A UDP listen side on 127.0.0.1 at an ephemeral port and a connect side sending to it.
namespace fnmpc::link::testing {

inline LinkAddress Udp(LinkAddress::Kind kind, int port) {
  LinkAddress a;
  a.kind = kind;
  a.host = "127.0.0.1";
  a.port = port;
  return a;
}

struct UdpPair {
  std::unique_ptr<UdpTransport> listen =
      std::make_unique<UdpTransport>(Udp(LinkAddress::Kind::kUdpListen, 0));
  std::unique_ptr<UdpTransport> connect =
      std::make_unique<UdpTransport>(Udp(LinkAddress::Kind::kUdpConnect, listen->local_port()));
};

}  // namespace fnmpc::link::testing

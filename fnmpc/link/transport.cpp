// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/transport.hpp"

#include "fnmpc/link/serial_transport.hpp"
#include "fnmpc/link/udp_transport.hpp"

namespace fnmpc::link {

std::unique_ptr<Transport> OpenTransport(const LinkAddress& address) {
  if (address.kind == LinkAddress::Kind::kSerial) {
    return std::make_unique<SerialTransport>(address);
  }
  return std::make_unique<UdpTransport>(address);
}

}  // namespace fnmpc::link

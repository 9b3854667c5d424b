// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <netinet/in.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "fnmpc/link/link_address.hpp"
#include "fnmpc/link/posix_fd.hpp"
#include "fnmpc/link/transport.hpp"

namespace fnmpc::link {

/// MAVLink over UDP/IPv4 (one frame or more per datagram), on a non-blocking socket.
///
/// kUdpListen binds host:port and has no peer until a datagram holding a valid frame of the
/// expected sender arrives (ConfirmLastSender, called by MavlinkConnection); it then replies
/// to the sender of the last such datagram (a flight controller that restarts from another
/// port is followed). A junk datagram, or one from another sender, never redirects the
/// replies. Port 0 binds an ephemeral port (local_port(); for tests, ParseLinkAddress does
/// not accept it).
///
/// kUdpConnect sends to host:port from an ephemeral local port and reads the datagrams that
/// arrive there, from any sender (the socket is not connect()ed, so that an autopilot
/// answering from another port is heard).
class UdpTransport : public Transport {
 public:
  /// Resolves the host (numeric IPv4 or a name, IPv4 only), creates and binds the socket.
  /// Throws std::runtime_error naming the address and the errno (or resolver) text.
  explicit UdpTransport(const LinkAddress& address);

  std::size_t Read(std::span<std::uint8_t> buffer, double timeout) override;
  bool Write(std::span<const std::uint8_t> bytes) override;
  void ConfirmLastSender() override;
  [[nodiscard]] bool datagrams() const override { return true; }
  [[nodiscard]] std::string Describe() const override { return description_; }

  /// The bound local port (the ephemeral one for kUdpConnect or port 0).
  [[nodiscard]] int local_port() const { return local_port_; }
  /// True once a peer is known (always for kUdpConnect).
  [[nodiscard]] bool has_peer() const { return has_peer_; }
  /// Datagrams received (Read calls that returned a datagram).
  [[nodiscard]] std::uint64_t datagrams_received() const { return datagrams_received_; }

 private:
  // Reads one datagram into `buffer` (*n bytes); false when none is waiting.
  bool Receive(std::span<std::uint8_t> buffer, std::size_t* n);

  std::string description_;
  UniqueFd fd_;
  bool listen_ = false;
  sockaddr_in peer_{};
  sockaddr_in last_sender_{};
  bool has_peer_ = false;
  int local_port_ = 0;
  std::uint64_t datagrams_received_ = 0;
};

}  // namespace fnmpc::link

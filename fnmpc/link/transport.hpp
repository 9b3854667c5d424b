// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "fnmpc/link/link_address.hpp"

/// A byte link to the flight controller (UDP or serial).
namespace fnmpc::link {

/// Reads and writes bytes on one link. Not thread-safe.
class Transport {
 public:
  virtual ~Transport() = default;

  /// Waits up to `timeout` [s] (0: does not wait) for bytes and reads what is available (for
  /// UDP one datagram, truncated to the buffer) into `buffer`; returns the number of bytes
  /// (0 on timeout). EINTR is retried. Throws std::runtime_error naming the link and the
  /// errno text on a fatal error.
  virtual std::size_t Read(std::span<std::uint8_t> buffer, double timeout) = 0;

  /// Sends `bytes` (one datagram for UDP); false when they cannot be sent now (UDP listen
  /// side with no peer yet, EAGAIN/ENOBUFS, ECONNREFUSED from a closed peer port, network
  /// unreachable; serial: not all written within a short bound). Throws std::runtime_error
  /// on a fatal error.
  virtual bool Write(std::span<const std::uint8_t> bytes) = 0;

  /// The last chunk Read returned held a valid frame of the peer we talk to: a transport that
  /// learns its peer (UDP listen) replies to that sender from now on. Nothing else, no junk
  /// datagram and no other sender, ever redirects the replies. No-op for the others.
  virtual void ConfirmLastSender() {}

  /// Read returns whole units of the sender (UDP datagrams), not arbitrary byte chunks.
  [[nodiscard]] virtual bool datagrams() const { return false; }

  /// The link, e.g. "udpout:127.0.0.1:14540" (for logs).
  [[nodiscard]] virtual std::string Describe() const = 0;
};

/// Opens the transport of `address`: a UdpTransport or a SerialTransport. Throws
/// std::runtime_error with the address and the errno text when the socket or device cannot
/// be opened, bound or configured, std::invalid_argument for an unsupported baud.
std::unique_ptr<Transport> OpenTransport(const LinkAddress& address);

}  // namespace fnmpc::link

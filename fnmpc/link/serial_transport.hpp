// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "fnmpc/link/link_address.hpp"
#include "fnmpc/link/posix_fd.hpp"
#include "fnmpc/link/transport.hpp"

namespace fnmpc::link {

/// The baud rates SerialTransport supports, ascending.
std::span<const int> SupportedBauds();

/// MAVLink over a serial device (a flight controller's USB CDC-ACM port or a UART), through
/// termios: raw 8N1, no flow control, no echo, opened O_NOCTTY | O_NONBLOCK; the input
/// buffered before opening is flushed.
class SerialTransport : public Transport {
 public:
  /// How long Write waits for room in the output buffer [s] before it gives up.
  static constexpr double kWriteTimeout = 0.05;

  /// Opens and configures address.device at address.baud. Throws std::invalid_argument for a
  /// baud not in SupportedBauds() (the message lists them), std::runtime_error naming the
  /// device and the errno text when it cannot be opened or configured.
  explicit SerialTransport(const LinkAddress& address);

  /// Reads what is available (at most buffer.size() bytes). Throws std::runtime_error when
  /// the device fails or hangs up (e.g. unplugged).
  std::size_t Read(std::span<std::uint8_t> buffer, double timeout) override;
  /// Writes all of `bytes`, waiting for room up to kWriteTimeout; false when they were not
  /// all written by then (the receiver's parser drops the cut frame).
  bool Write(std::span<const std::uint8_t> bytes) override;
  [[nodiscard]] std::string Describe() const override { return description_; }

 private:
  std::string description_;
  UniqueFd fd_;
};

}  // namespace fnmpc::link

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

/// The MAVLink checksum: CRC-16/MCRF4XX (the "X.25" CRC of the MAVLink documentation):
/// polynomial x^16 + x^12 + x^5 + 1 processed least significant bit first (reflected
/// polynomial 0x8408), initial value 0xFFFF, no final XOR. A frame's checksum covers every
/// byte after the start byte up to the end of the payload, then the message's CRC_EXTRA
/// byte (mavlink.io/en/guide/serialization.html, "Checksum"). Check value:
/// Crc16("123456789") = 0x6F91.
namespace fnmpc::mavlink {

/// Initial value of the CRC register.
inline constexpr std::uint16_t kCrcInit = 0xFFFF;

/// Feeds one byte into the CRC register `crc` and returns the new register.
constexpr std::uint16_t CrcAccumulate(std::uint8_t byte, std::uint16_t crc) {
  crc ^= byte;
  for (int bit = 0; bit < 8; ++bit) {
    crc = (crc & 1U) != 0 ? static_cast<std::uint16_t>((crc >> 1) ^ 0x8408U)
                          : static_cast<std::uint16_t>(crc >> 1);
  }
  return crc;
}

/// Feeds `bytes` into the register `crc` (kCrcInit to start a new checksum).
constexpr std::uint16_t CrcAccumulate(std::span<const std::uint8_t> bytes,
                                      std::uint16_t crc = kCrcInit) {
  for (const std::uint8_t b : bytes) crc = CrcAccumulate(b, crc);
  return crc;
}

/// Feeds the characters of `text` into the register `crc` (used for CRC_EXTRA, which is
/// computed over the message definition's text).
constexpr std::uint16_t CrcAccumulate(std::string_view text, std::uint16_t crc = kCrcInit) {
  for (const char c : text) crc = CrcAccumulate(static_cast<std::uint8_t>(c), crc);
  return crc;
}

}  // namespace fnmpc::mavlink

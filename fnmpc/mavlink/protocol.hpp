// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

/// MAVLink 2 frame layout (mavlink.io/en/guide/serialization.html, "MAVLink 2 Packet
/// Format"), all multi-byte values little-endian:
///
///   offset  size  field
///   0       1     start byte 0xFD
///   1       1     payload length (0-255)
///   2       1     incompatibility flags (0x01: signed)
///   3       1     compatibility flags
///   4       1     sequence number
///   5       1     system id
///   6       1     component id
///   7       3     message id (24 bits)
///   10      len   payload
///   10+len  2     checksum: CRC-16/MCRF4XX over bytes 1 .. 9+len, then CRC_EXTRA
///   12+len  13    signature (when signed): link id (1), timestamp (6), signature (6)
///
/// MAVLink 1 frames (start byte 0xFE) are not supported.
namespace fnmpc::mavlink {

inline constexpr std::uint8_t kStartByte = 0xFD;       ///< MAVLink 2 start byte (STX)
inline constexpr std::size_t kHeaderLength = 10;       ///< start byte to message id [bytes]
inline constexpr std::size_t kChecksumLength = 2;      ///< [bytes]
inline constexpr std::size_t kSignatureLength = 13;    ///< link id + timestamp + signature
inline constexpr std::size_t kMaxPayloadLength = 255;  ///< [bytes]
inline constexpr std::size_t kMaxFrameLength =
    kHeaderLength + kMaxPayloadLength + kChecksumLength + kSignatureLength;  ///< 280 bytes
inline constexpr std::uint8_t kIncompatFlagSigned = 0x01;  ///< incompatibility flag: signed
/// Incompatibility flags this implementation understands; a frame with any other one set
/// must be dropped (the spec: an unknown incompatibility flag means the frame cannot be read).
inline constexpr std::uint8_t kSupportedIncompatFlags = kIncompatFlagSigned;

/// The header fields of a frame (without the start byte).
struct FrameHeader {
  std::uint8_t payload_length{};  ///< payload bytes on the wire (after truncation)
  std::uint8_t incompat_flags{};  ///< incompatibility flags
  std::uint8_t compat_flags{};    ///< compatibility flags
  std::uint8_t sequence{};        ///< per-sender sequence number, wraps at 255
  std::uint8_t system_id{};       ///< sender's system id
  std::uint8_t component_id{};    ///< sender's component id
  std::uint32_t message_id{};     ///< message id (24 bits)
  friend bool operator==(const FrameHeader&, const FrameHeader&) = default;
};

/// The 13-byte signature block of a signed frame.
struct FrameSignature {
  std::uint8_t link_id{};               ///< the sender's link (channel) id
  std::uint64_t timestamp{};            ///< [10 us] since 2015-01-01 00:00:00 UTC (48 bits)
  std::array<std::uint8_t, 6> value{};  ///< first 6 bytes of the SHA-256 (signing.hpp)
  friend bool operator==(const FrameSignature&, const FrameSignature&) = default;
};

/// MAVLink 2 payload truncation: the length of `payload` without its trailing zero bytes,
/// but at least 1 (the spec: the first byte of the payload is never truncated, even when
/// the whole payload is zero). An empty payload stays empty.
constexpr std::size_t TruncatedPayloadLength(std::span<const std::uint8_t> payload) {
  std::size_t n = payload.size();
  while (n > 1 && payload[n - 1] == 0) --n;
  return n;
}

}  // namespace fnmpc::mavlink

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "fnmpc/mavlink/protocol.hpp"

/// MAVLink 2 message signing (mavlink.io/en/guide/message_signing.html). A signed frame has
/// incompatibility flag 0x01 and 13 bytes after its checksum:
///   link id (1 byte), timestamp (6 bytes, little-endian, 10 us units since
///   2015-01-01 00:00:00 UTC), signature (6 bytes) = the first 6 bytes of
///   SHA-256(secret key (32 bytes) + header (10 bytes, from the start byte) + payload
///               + checksum (2 bytes) + link id + timestamp).
/// The secret key is shared by the sender and the receivers (how it is agreed on is not
/// part of this layer).
namespace fnmpc::mavlink {

/// The 32-byte shared secret.
using SigningKey = std::array<std::uint8_t, 32>;

/// The signature epoch 2015-01-01 00:00:00 UTC as Unix time [us].
inline constexpr std::uint64_t kSigningEpochUnixUs = 1420070400ULL * 1000000ULL;
/// Largest signature timestamp (48 bits) [10 us].
inline constexpr std::uint64_t kMaxSigningTimestamp = (1ULL << 48) - 1;
/// A receiver accepts the first frame of a new stream only when its timestamp is at most
/// this far behind the newest timestamp it knows (the spec's one minute) [10 us].
inline constexpr std::uint64_t kNewStreamTimestampWindow = 6000000;

/// Signature timestamp [10 us since 2015-01-01] of a Unix time [us] (0 before the epoch).
constexpr std::uint64_t SigningTimestampFromUnixUs(std::uint64_t unix_us) {
  return unix_us <= kSigningEpochUnixUs ? 0 : (unix_us - kSigningEpochUnixUs) / 10;
}

/// The 6-byte signature of a frame. `frame` holds the frame from its start byte to the end
/// of its checksum (with the signed flag already set in its header).
std::array<std::uint8_t, 6> ComputeSignature(const SigningKey& key,
                                             std::span<const std::uint8_t> frame,
                                             std::uint8_t link_id, std::uint64_t timestamp);

}  // namespace fnmpc::mavlink

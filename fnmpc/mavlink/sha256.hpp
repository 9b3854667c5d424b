// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

/// SHA-256 (FIPS 180-4, section 6.2), our own implementation for MAVLink 2 message signing.
/// Streaming: Update() any number of times, then Final(). No allocation; the state is 108
/// bytes. Checked against the FIPS 180-4 example vectors (tests/mavlink/sha256_test.cpp).
namespace fnmpc::mavlink {

/// A SHA-256 digest (32 bytes, big-endian words as the standard prints them).
using Sha256Digest = std::array<std::uint8_t, 32>;

class Sha256 {
 public:
  Sha256();

  /// Appends `bytes` to the message.
  void Update(std::span<const std::uint8_t> bytes);

  /// Pads the message, returns its digest and resets the object to an empty message.
  Sha256Digest Final();

  /// Digest of one contiguous message.
  static Sha256Digest Hash(std::span<const std::uint8_t> bytes);

 private:
  void Reset();
  void Compress(const std::uint8_t* block);

  std::array<std::uint32_t, 8> h_{};      ///< intermediate hash value H(i)
  std::array<std::uint8_t, 64> block_{};  ///< pending bytes of the current 512-bit block
  std::size_t block_used_ = 0;            ///< bytes in block_
  std::uint64_t length_bytes_ = 0;        ///< message length so far [bytes]
};

}  // namespace fnmpc::mavlink

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "fnmpc/mavlink/message.hpp"
#include "fnmpc/mavlink/protocol.hpp"
#include "fnmpc/mavlink/signing.hpp"

/// MAVLink 2 frame writing. No allocation: frames go into a caller's buffer, at most
/// kMaxFrameLength (280) bytes each.
namespace fnmpc::mavlink {

/// Everything a frame carries besides its payload (WriteFrame).
struct FrameSpec {
  std::uint8_t sequence = 0;        ///< sequence number
  std::uint8_t system_id = 0;       ///< sender's system id
  std::uint8_t component_id = 0;    ///< sender's component id
  std::uint8_t compat_flags = 0;    ///< compatibility flags (none defined; 0)
  std::uint32_t message_id = 0;     ///< message id (< 2^24)
  std::uint8_t crc_extra = 0;       ///< the message's CRC_EXTRA
  const SigningKey* key = nullptr;  ///< sign the frame with this key; nullptr: unsigned
  std::uint8_t link_id = 0;         ///< signature link id (signed frames)
  std::uint64_t timestamp = 0;      ///< signature timestamp [10 us since 2015-01-01] (signed)
};

/// Writes one frame carrying exactly `payload` (not truncated here: the low-level writer,
/// also for frames of unsupported ids in tests) to the front of `out`. Returns the frame's
/// length, or 0 when `out` is too small, the payload longer than 255 bytes, the id 2^24 or
/// more, or the timestamp wider than 48 bits.
std::size_t WriteFrame(const FrameSpec& spec, std::span<const std::uint8_t> payload,
                       std::span<std::uint8_t> out);

/// Encodes supported messages as MAVLink 2 frames of one sender (system id, component id):
/// packs the payload, truncates its trailing zero bytes (keeping the first byte), numbers
/// the frames (sequence 0, 1, ..., 255, 0, ...) and, when signing is enabled, signs them.
///
/// Signing needs the time: SetTimestamp() gives the encoder the current time in signature
/// units, and each signed frame carries max(that time, previous frame's timestamp + 1), so
/// that timestamps strictly increase even when the clock has not advanced between frames
/// (as the signing spec asks of senders). The encoder reads no clock itself.
class Encoder {
 public:
  /// A sender with system id `system_id` and component id `component_id`.
  Encoder(std::uint8_t system_id, std::uint8_t component_id);

  /// Signs every later frame with `key` on link `link_id`.
  void EnableSigning(const SigningKey& key, std::uint8_t link_id);
  /// Sends unsigned frames again (the key is wiped).
  void DisableSigning();
  /// True while frames are signed.
  bool signing() const { return signing_; }

  /// The current time [10 us since 2015-01-01 00:00:00 UTC] (SigningTimestampFromUnixUs).
  void SetTimestamp(std::uint64_t timestamp) { clock_ = timestamp; }

  /// Writes the frame of `message` to the front of `out` and returns its length; returns 0
  /// when `out` is too small (no sequence number or timestamp is used up then).
  /// kMaxFrameLength bytes are always enough.
  std::size_t Encode(const Message& message, std::span<std::uint8_t> out);
  /// The same for a message this codec has no struct for: its id, CRC_EXTRA (from the
  /// message's XML definition) and packed payload, which is truncated, numbered and signed
  /// like every other frame.
  std::size_t EncodePayload(std::uint32_t message_id, std::uint8_t crc_extra,
                            std::span<const std::uint8_t> payload, std::span<std::uint8_t> out);

  /// Sequence number of the next frame.
  std::uint8_t sequence() const { return sequence_; }
  void set_sequence(std::uint8_t sequence) { sequence_ = sequence; }
  /// Timestamp of the last signed frame (0 before the first).
  std::uint64_t last_timestamp() const { return last_timestamp_; }
  std::uint8_t system_id() const { return system_id_; }
  std::uint8_t component_id() const { return component_id_; }

 private:
  std::uint8_t system_id_;
  std::uint8_t component_id_;
  std::uint8_t sequence_ = 0;
  bool signing_ = false;
  SigningKey key_{};
  std::uint8_t link_id_ = 0;
  std::uint64_t clock_ = 0;           // SetTimestamp's value [10 us]
  std::uint64_t last_timestamp_ = 0;  // of the last signed frame [10 us]
  bool signed_any_ = false;
};

}  // namespace fnmpc::mavlink

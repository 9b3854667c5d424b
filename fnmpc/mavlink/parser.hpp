// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "fnmpc/mavlink/message.hpp"
#include "fnmpc/mavlink/protocol.hpp"
#include "fnmpc/mavlink/signing.hpp"

/// MAVLink 2 stream parsing.
namespace fnmpc::mavlink {

/// A decoded frame.
struct Frame {
  FrameHeader header;        ///< header fields as received
  std::uint16_t checksum{};  ///< the frame's checksum (verified)
  bool is_signed = false;    ///< incompatibility flag 0x01 set
  FrameSignature signature;  ///< the signature block when is_signed (verified if a key is set)
  Message message;           ///< the decoded payload (truncated bytes read as zero)
  /// The frame's bytes as received, start byte to signature. Points into the parser: valid
  /// only until the parser is fed again (copy it to keep it).
  std::span<const std::uint8_t> bytes;
};

/// What a parser has seen since construction (or ResetCounters). Every received byte ends
/// in a decoded frame, in a frame of a message id it does not know, or is discarded, or is
/// still buffered:
///   bytes_received == bytes_in_frames + bytes_in_unknown_frames + bytes_discarded
///                     + Parser::buffered().
/// Each failed frame candidate counts once, under the first check it fails; the checks, in
/// order: incompatibility flags, message id, payload length (at the header), checksum,
/// signature (with a key set).
///
/// Unknown message ids. A real autopilot sends many messages this codec does not decode.
/// Their checksum cannot be verified (it needs the message's CRC_EXTRA), so they are never
/// trusted on their own: the parser resynchronises through them as through garbage, and every
/// valid frame inside survives. But when a run of unknown-id headers of one sender (system
/// and component), each starting exactly where the one before ends by its declared length
/// and numbered one after it (the sender's sequence), is followed by a valid frame of that
/// sender with the next sequence number starting exactly at the run's end, the run was real
/// traffic: its bytes move from bytes_discarded to
/// bytes_in_unknown_frames, it counts in unknown_frames, and the failed candidates of false
/// start bytes inside it are taken back from the failure counters. A healthy stream thus shows
/// zero discarded bytes and zero failures (its last unknown frames stay counted as discarded
/// until the next valid frame arrives, or the end of their datagram, EndOfDatagram).
struct ParserCounters {
  std::uint64_t bytes_received = 0;           ///< bytes fed in
  std::uint64_t frames_ok = 0;                ///< frames decoded and handed out
  std::uint64_t bytes_in_frames = 0;          ///< bytes of those frames
  std::uint64_t bytes_discarded = 0;          ///< bytes not part of any decoded frame
  std::uint64_t crc_errors = 0;               ///< complete candidates whose checksum is wrong
  std::uint64_t unknown_ids = 0;              ///< headers with an unsupported message id
  std::uint64_t unknown_frames = 0;           ///< frames of an unsupported id, skipped (above)
  std::uint64_t bytes_in_unknown_frames = 0;  ///< bytes of those frames
  std::uint64_t bad_lengths = 0;              ///< payload longer than the message's max length
  std::uint64_t bad_incompat_flags = 0;       ///< headers with an unknown incompatibility flag
  /// Frames with a valid checksum rejected by signing (key set): the sum of the next three.
  std::uint64_t signature_failures = 0;
  std::uint64_t unsigned_rejected = 0;    ///< unsigned frame while a key is set
  std::uint64_t bad_signatures = 0;       ///< signature does not match the key
  std::uint64_t timestamps_rejected = 0;  ///< timestamp not newer than its stream's last
                                          ///< (or a new stream more than 1 min behind)
};

/// Byte-at-a-time MAVLink 2 parser: finds the start byte 0xFD, reads the header, payload,
/// checksum and (incompatibility flag 0x01) signature, verifies, decodes and hands each
/// frame of a supported message to a callback.
///
/// Checks. At the header: no unknown incompatibility flag; a supported message id (the
/// checksum of an unsupported id cannot be verified without its CRC_EXTRA, so its length is
/// not trusted either); payload length at most the message's max length (a payload of 0 to
/// max length bytes is accepted: senders truncate trailing zeros, and read as zeros). At the
/// end: the checksum; with a signing key set, the frame must be signed, its signature must
/// match, and its timestamp must be newer than the last one accepted from the same stream
/// (link id, system id, component id); a stream seen for the first time must not be more than
/// one minute behind the newest timestamp the parser knows (SetTimestamp, or any accepted
/// frame). Without a key, signed frames are accepted and their signature exposed unverified
/// (what the spec asks of systems that do not sign).
///
/// Resynchronisation. A candidate that fails a check gives up only its start byte: the
/// parser rescans the bytes after it for the next 0xFD, so a false start (a 0xFD inside
/// garbage or inside another frame's payload) never swallows a valid frame that follows; at
/// worst it delays it until the false candidate is complete and fails its checksum.
///
/// No allocation and no I/O: one fixed buffer of kMaxFrameLength bytes. Not thread-safe.
class Parser {
 public:
  /// Streams tracked for signature timestamps; when full, the stream with the oldest
  /// timestamp is forgotten (its next frame is then held to the new-stream window).
  static constexpr std::size_t kMaxSigningStreams = 16;

  Parser() = default;

  /// Accepts only frames signed with `key` from now on.
  void SetSigningKey(const SigningKey& key);
  /// Accepts unsigned frames again; forgets the key and the streams' timestamps.
  void ClearSigningKey();
  /// True while a key is set.
  bool signing() const { return signing_; }
  /// The current time [10 us since 2015-01-01 00:00:00 UTC], for the new-stream window
  /// (optional: without it the newest accepted timestamp serves).
  void SetTimestamp(std::uint64_t timestamp);

  /// Feeds one byte; calls on_frame(const Frame&) for each frame it completes (none, one, or,
  /// after a false start is resolved, several).
  template <class OnFrame>
  void Parse(std::uint8_t byte, OnFrame&& on_frame) {
    Append(byte);
    while (Next()) on_frame(static_cast<const Frame&>(frame_));
  }

  /// Feeds `bytes` one at a time (same as calling Parse(byte) for each).
  template <class OnFrame>
  void Parse(std::span<const std::uint8_t> bytes, OnFrame&& on_frame) {
    for (const std::uint8_t b : bytes) Parse(b, on_frame);
  }

  /// The sender's unit of bytes (a UDP datagram, which holds whole frames) ends here: a run
  /// of unknown frames that ends exactly here is confirmed as if a valid frame followed, and
  /// a false start still buffered inside its last frame is dropped with it.
  void EndOfDatagram();

  /// Drops the buffered bytes of an incomplete frame (counted as discarded), e.g. after a
  /// link was reopened.
  void Reset();
  /// Zeroes the counters (the buffered bytes are then not in bytes_received).
  void ResetCounters() {
    counters_ = ParserCounters{};
    run_active_ = false;
  }

  const ParserCounters& counters() const { return counters_; }
  /// Bytes held for a frame not yet complete.
  std::size_t buffered() const { return end_; }

 private:
  struct SigningStream {
    bool used = false;
    std::uint8_t link_id = 0;
    std::uint8_t system_id = 0;
    std::uint8_t component_id = 0;
    std::uint64_t timestamp = 0;
  };

  void Append(std::uint8_t byte);
  // Processes buffered bytes; true when frame_ holds a new frame.
  bool Next();
  // Header checks; on success sets expected_.
  bool HeaderOk();
  // Checksum, signature and decoding of the complete candidate; true when decoded.
  bool CompleteOk();
  // Signing checks (key set) of the candidate whose checksum ends at crc_end: nullptr when
  // it passes, else the counter of the failed check.
  std::uint64_t* SignatureFailure(std::size_t crc_end);
  // Gives up the candidate's start byte: discards up to the next start byte after it.
  void Fail(std::uint64_t* counter);
  void Discard(std::size_t n);
  // Stream offset of buf_[0].
  [[nodiscard]] std::uint64_t Offset() const { return counters_.bytes_received - end_; }
  // An unknown-id header at buf_[0] (before its failure is counted).
  void NoteUnknown(std::size_t frame_length);
  // A valid frame at buf_[0] (or the datagram's end): confirms the run of unknown frames
  // that ends there.
  void ConfirmUnknownRun(bool datagram_end);
  // The frame (system, component, sequence) is the next one of the run's sender.
  [[nodiscard]] bool Follows(std::uint8_t system, std::uint8_t component,
                             std::uint8_t sequence) const;

  // The current run of unknown-id frames (see ParserCounters): stream offsets, frames, and
  // the counters as they were before its first header.
  bool run_active_ = false;
  std::uint64_t run_start_ = 0, run_end_ = 0, run_frames_ = 0;
  std::uint8_t run_system_ = 0, run_component_ = 0, run_sequence_ = 0;  // of its last frame
  ParserCounters run_before_;

  std::array<std::uint8_t, kMaxFrameLength> buf_{};  // candidate, then unprocessed bytes
  std::size_t end_ = 0;                              // bytes in buf_
  std::size_t pos_ = 0;                // bytes of buf_ processed (the candidate's length)
  std::size_t expected_ = 0;           // candidate's full length, known after its header
  const MessageInfo* info_ = nullptr;  // candidate's message
  bool emitted_ = false;  // frame_ refers to buf_[0, expected_): remove before going on
  Frame frame_;
  ParserCounters counters_;

  bool signing_ = false;
  SigningKey key_{};
  std::array<SigningStream, kMaxSigningStreams> streams_{};
  std::uint64_t newest_timestamp_ = 0;
};

}  // namespace fnmpc::mavlink

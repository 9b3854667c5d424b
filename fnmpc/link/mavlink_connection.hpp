// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>

#include "fnmpc/link/transport.hpp"
#include "fnmpc/mavlink/encoder.hpp"
#include "fnmpc/mavlink/message.hpp"
#include "fnmpc/mavlink/parser.hpp"
#include "fnmpc/mavlink/protocol.hpp"

namespace fnmpc::link {

/// One MAVLink 2 endpoint over a transport: an encoder (our system and component id) and a
/// stream parser. No allocation after construction: fixed frame and read buffers (the
/// transports' Read and Write allocate nothing either, except to throw). Not thread-safe.
class MavlinkConnection {
 public:
  /// Read buffer [bytes]: a UDP datagram longer than this is truncated (a serial read takes
  /// at most this much; the rest waits for the next read).
  static constexpr std::size_t kReadBufferSize = 4096;
  /// Reads per Poll: one with the timeout, then up to kMaxReadsPerPoll - 1 without waiting.
  static constexpr int kMaxReadsPerPoll = 64;

  MavlinkConnection(std::unique_ptr<Transport> transport, std::uint8_t system_id,
                    std::uint8_t component_id);

  /// Encodes and writes one message; false when the transport could not send it (counted in
  /// send_failures(); the frame's sequence number is used up). Throws what the transport
  /// throws on a fatal error.
  bool Send(const mavlink::Message& message);
  /// Writes one frame of a message this codec does not decode: id, its CRC_EXTRA and the
  /// packed payload (the simulator's endpoint plays an autopilot's other traffic with it).
  /// Truncated, numbered, signed and counted as Send's frames (mavlink::Encoder::EncodePayload).
  bool SendOther(std::uint32_t message_id, std::uint8_t crc_extra,
                 std::span<const std::uint8_t> payload);

  /// Waits up to `timeout` [s] for bytes, reads once, parses them and calls
  /// on_frame(const mavlink::Frame&) per decoded frame; then reads on without waiting while
  /// bytes are immediately available (a burst is drained), at most kMaxReadsPerPoll reads in
  /// all. Returns the number of frames decoded. The frame (and its bytes) is valid only
  /// during the call.
  ///
  /// A chunk that held a valid frame of the expected peer (ExpectPeer; by default any valid
  /// frame) confirms its sender to the transport (Transport::ConfirmLastSender).
  template <class OnFrame>
  int Poll(double timeout, OnFrame&& on_frame) {
    int frames = 0;
    bool from_peer = false;
    UpdateSigningTime();
    auto count = [&](const mavlink::Frame& frame) {
      ++frames;
      from_peer = from_peer || IsPeer(frame.header);
      on_frame(frame);
    };
    std::size_t n = transport_->Read(read_buffer_, timeout);
    for (int reads = 1; n > 0; ++reads) {
      from_peer = false;
      parser_.Parse(std::span<const std::uint8_t>(read_buffer_.data(), n), count);
      if (from_peer) transport_->ConfirmLastSender();
      if (transport_->datagrams()) parser_.EndOfDatagram();
      if (reads >= kMaxReadsPerPoll) break;
      n = transport_->Read(read_buffer_, 0.0);
    }
    return frames;
  }

  /// Signs every frame sent with `key` on link `link_id` and accepts only frames signed with
  /// it (the parser's checks: docs/mavlink.md "Signing"). The signature timestamps come from
  /// the system clock (10 us since 2015-01-01), set before every send and poll.
  void EnableSigning(const mavlink::SigningKey& key, std::uint8_t link_id);
  [[nodiscard]] bool signing() const { return encoder_.signing(); }

  /// Only frames of (system_id, component_id) confirm a sender (0: any id in that place).
  void ExpectPeer(std::uint8_t system_id, std::uint8_t component_id) {
    peer_system_ = system_id;
    peer_component_ = component_id;
  }

  /// The parser's counters: bytes received, frames decoded, bytes discarded, failed checks.
  [[nodiscard]] const mavlink::ParserCounters& counters() const { return parser_.counters(); }
  /// Messages Send could not send.
  [[nodiscard]] std::uint64_t send_failures() const { return send_failures_; }
  /// Messages Send sent.
  [[nodiscard]] std::uint64_t frames_sent() const { return frames_sent_; }

  /// The encoder (signing, sequence numbers).
  mavlink::Encoder& encoder() { return encoder_; }
  /// The parser (signing key, counters reset).
  mavlink::Parser& parser() { return parser_; }
  Transport& transport() { return *transport_; }

 private:
  std::unique_ptr<Transport> transport_;
  mavlink::Encoder encoder_;
  mavlink::Parser parser_;
  std::array<std::uint8_t, mavlink::kMaxFrameLength> frame_buffer_{};
  std::array<std::uint8_t, kReadBufferSize> read_buffer_{};
  void UpdateSigningTime();
  [[nodiscard]] bool IsPeer(const mavlink::FrameHeader& h) const {
    return (peer_system_ == 0 || h.system_id == peer_system_) &&
           (peer_component_ == 0 || h.component_id == peer_component_);
  }

  std::uint8_t peer_system_ = 0, peer_component_ = 0;
  std::uint64_t send_failures_ = 0;
  std::uint64_t frames_sent_ = 0;
};

}  // namespace fnmpc::link

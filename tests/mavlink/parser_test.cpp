// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/parser.hpp"

#include <gtest/gtest.h>

#include <array>
#include <random>
#include <vector>

#include "fnmpc/mavlink/encoder.hpp"
#include "tests/mavlink/sample_messages.hpp"

namespace fnmpc::mavlink {
namespace {

using testing::EncodeToVector;
using testing::RandomMessage;
using testing::SamePayload;

using Bytes = std::vector<std::uint8_t>;

struct Received {
  FrameHeader header;
  Message message;
  Bytes bytes;
  bool is_signed = false;
};

// Feeds `stream` one byte at a time and keeps copies of the decoded frames.
std::vector<Received> ParseAll(Parser* parser, const Bytes& stream) {
  std::vector<Received> out;
  parser->Parse(stream, [&](const Frame& f) {
    out.push_back({f.header, f.message, Bytes(f.bytes.begin(), f.bytes.end()), f.is_signed});
  });
  return out;
}

void ExpectConservation(const Parser& p) {
  const ParserCounters& c = p.counters();
  EXPECT_EQ(c.bytes_received,
            c.bytes_in_frames + c.bytes_in_unknown_frames + c.bytes_discarded + p.buffered());
}

Bytes Concat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const Bytes& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

// A frame written with exactly `payload` (no truncation) and any id and CRC_EXTRA.
Bytes RawFrame(std::uint32_t id, std::uint8_t crc_extra, const Bytes& payload,
               std::uint8_t sequence = 0) {
  FrameSpec spec;
  spec.message_id = id;
  spec.crc_extra = crc_extra;
  spec.sequence = sequence;
  spec.system_id = 1;
  spec.component_id = 1;
  std::array<std::uint8_t, kMaxFrameLength> out{};
  const std::size_t n = WriteFrame(spec, payload, out);
  return {out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n)};
}

TEST(ParserTest, DecodesAFrameWithItsHeader) {
  // Given an encoded ATTITUDE from 9/190 with sequence 17
  Encoder encoder(9, 190);
  encoder.set_sequence(17);
  const Attitude att{.time_boot_ms = 1234,
                     .roll = 0.1F,
                     .pitch = -0.2F,
                     .yaw = 3.0F,
                     .rollspeed = 0.01F,
                     .pitchspeed = 0.02F,
                     .yawspeed = -0.03F};
  const Bytes f = EncodeToVector(&encoder, att);
  // When it is parsed
  Parser parser;
  const auto got = ParseAll(&parser, f);
  // Then one frame with the header fields and the message comes out
  ASSERT_EQ(got.size(), 1U);
  EXPECT_EQ(got[0].header.sequence, 17);
  EXPECT_EQ(got[0].header.system_id, 9);
  EXPECT_EQ(got[0].header.component_id, 190);
  EXPECT_EQ(got[0].header.message_id, Attitude::kId);
  EXPECT_EQ(got[0].header.payload_length, 28);
  EXPECT_FALSE(got[0].is_signed);
  EXPECT_EQ(std::get<Attitude>(got[0].message), att);
  EXPECT_EQ(got[0].bytes, f);
  EXPECT_EQ(parser.counters().frames_ok, 1U);
  EXPECT_EQ(parser.counters().bytes_discarded, 0U);
  EXPECT_EQ(parser.buffered(), 0U);
  ExpectConservation(parser);
}

TEST(ParserTest, TruncatedUntruncatedAndEmptyPayloadsAllDecode) {
  // Given one message as a truncated frame, an untruncated one, and a zero message with an
  // empty payload (not what the spec's senders do, but a valid checksum)
  const CommandAck ack{.command = 400, .result = 0};
  Encoder encoder(1, 1);
  const Bytes truncated = EncodeToVector(&encoder, ack);
  std::array<std::uint8_t, kMaxPayloadLength> payload{};
  PackPayload(Message{ack}, payload);
  const Bytes full = RawFrame(CommandAck::kId, CommandAck::kCrcExtra,
                              Bytes(payload.begin(), payload.begin() + CommandAck::kMaxLength));
  const Bytes empty = RawFrame(Heartbeat::kId, Heartbeat::kCrcExtra, {});
  ASSERT_LT(truncated.size(), full.size());
  // When they are parsed
  Parser parser;
  const auto got = ParseAll(&parser, Concat({truncated, full, empty}));
  // Then all three decode
  ASSERT_EQ(got.size(), 3U);
  EXPECT_EQ(std::get<CommandAck>(got[0].message), ack);
  EXPECT_EQ(std::get<CommandAck>(got[1].message), ack);
  EXPECT_EQ(got[1].header.payload_length, CommandAck::kMaxLength);
  EXPECT_EQ(std::get<Heartbeat>(got[2].message), Heartbeat{});
  ExpectConservation(parser);
}

TEST(ParserTest, ResynchronisesThroughGarbageWithStartBytes) {
  // Given frames separated by garbage full of 0xFD (start bytes, false headers)
  std::mt19937 rng(5);
  Encoder encoder(1, 1);
  std::vector<Message> sent;
  Bytes stream;
  Bytes frames_only;
  for (int i = 0; i < 100; ++i) {
    Bytes garbage(rng() % 40);
    for (auto& b : garbage) b = rng() % 3 == 0 ? kStartByte : static_cast<std::uint8_t>(rng());
    stream.insert(stream.end(), garbage.begin(), garbage.end());
    sent.push_back(RandomMessage(&rng));
    const Bytes f = EncodeToVector(&encoder, sent.back());
    stream.insert(stream.end(), f.begin(), f.end());
    frames_only.insert(frames_only.end(), f.begin(), f.end());
  }
  stream.insert(stream.end(), 300, 0x55);  // let a last false candidate complete
  // When the stream is parsed
  Parser parser;
  const auto got = ParseAll(&parser, stream);
  // Then every frame comes out, in order, and the rest is discarded
  ASSERT_EQ(got.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i) {
    EXPECT_TRUE(SamePayload(got[i].message, sent[i])) << i;
    EXPECT_EQ(got[i].header.sequence, i % 256);
  }
  EXPECT_EQ(parser.counters().bytes_in_frames, frames_only.size());
  EXPECT_EQ(parser.counters().bytes_discarded, stream.size() - frames_only.size());
  EXPECT_EQ(parser.buffered(), 0U);
  ExpectConservation(parser);
}

TEST(ParserTest, FalseStartDoesNotSwallowTheFramesAfterIt) {
  // Given a false header (known id, long payload) followed by three short frames that fit
  // inside the length it claims
  Encoder encoder(1, 1);
  const Bytes a = EncodeToVector(&encoder, Heartbeat{.custom_mode = 1, .mavlink_version = 3});
  const Bytes b = EncodeToVector(&encoder, CommandAck{.command = 22, .result = 1});
  const Bytes c = EncodeToVector(&encoder, Heartbeat{.custom_mode = 2, .mavlink_version = 3});
  const Bytes false_header{0xFD, 200, 0, 0, 0, 1, 1, 0x4B, 0x01, 0x00};  // ODOMETRY, 200 bytes
  Bytes stream = Concat({false_header, a, b, c});
  Parser parser;
  std::size_t frames_at_end_of_c = 0;
  std::vector<Received> got;
  // When it is parsed: nothing comes out until the false candidate is complete
  for (std::size_t i = 0; i < stream.size(); ++i) {
    parser.Parse(stream[i], [&](const Frame& f) {
      got.push_back({f.header, f.message, Bytes(f.bytes.begin(), f.bytes.end()), false});
    });
  }
  frames_at_end_of_c = got.size();
  EXPECT_EQ(frames_at_end_of_c, 0U);
  // Then the byte that completes it (and fails its checksum) releases all three at once
  const Bytes padding(kHeaderLength + 200 + kChecksumLength - stream.size(), 0x00);
  std::size_t released_by_one_byte = 0;
  for (std::size_t i = 0; i < padding.size(); ++i) {
    const std::size_t before = got.size();
    parser.Parse(padding[i], [&](const Frame& f) {
      got.push_back({f.header, f.message, Bytes(f.bytes.begin(), f.bytes.end()), false});
    });
    released_by_one_byte = std::max(released_by_one_byte, got.size() - before);
  }
  ASSERT_EQ(got.size(), 3U);
  EXPECT_EQ(released_by_one_byte, 3U);
  EXPECT_EQ(got[0].bytes, a);
  EXPECT_EQ(got[1].bytes, b);
  EXPECT_EQ(got[2].bytes, c);
  EXPECT_EQ(parser.counters().crc_errors, 1U);
  EXPECT_EQ(parser.counters().bytes_discarded, false_header.size() + padding.size());
  ExpectConservation(parser);
}

TEST(ParserTest, RejectsUnknownIdsBadLengthsAndFlagsAndKeepsGoing) {
  // Given, each followed by a valid frame: an unsupported id (GPS_RAW_INT, 24), a HEARTBEAT
  // with 10 payload bytes (max 9), an unknown incompatibility flag, and a wrong checksum
  Encoder encoder(1, 1);
  const Bytes good = EncodeToVector(&encoder, Heartbeat{.custom_mode = 7, .mavlink_version = 3});
  const Bytes unknown = RawFrame(24, 24, Bytes(30, 0x11), 255);  // the frame before `good`
  const Bytes too_long = RawFrame(Heartbeat::kId, Heartbeat::kCrcExtra, Bytes(10, 0x22));
  Bytes flagged = good;
  flagged[2] = 0x02;
  Bytes bad_crc = good;
  bad_crc[kHeaderLength] ^= 0x40;
  const Bytes stream = Concat({unknown, good, too_long, good, flagged, good, bad_crc, good});
  // When it is parsed
  Parser parser;
  const auto got = ParseAll(&parser, stream);
  // Then each bad frame counts once under its reason and the good ones all decode
  EXPECT_EQ(got.size(), 4U);
  const ParserCounters& c = parser.counters();
  EXPECT_EQ(c.unknown_ids, 1U);
  EXPECT_EQ(c.bad_lengths, 1U);
  EXPECT_EQ(c.bad_incompat_flags, 1U);
  EXPECT_EQ(c.crc_errors, 1U);
  EXPECT_EQ(c.frames_ok, 4U);
  // The unknown frame, followed by a valid frame at its declared end, is skipped, not
  // discarded
  EXPECT_EQ(c.unknown_frames, 1U);
  EXPECT_EQ(c.bytes_in_unknown_frames, unknown.size());
  EXPECT_EQ(c.bytes_discarded, too_long.size() + flagged.size() + bad_crc.size());
  ExpectConservation(parser);
}

TEST(ParserTest, ARunOfUnknownFramesWithFalseStartsInsideIsSkippedWithoutFailures) {
  // Given what an autopilot sends: frames of ids we do not decode, back to back, one with
  // false start bytes in its payload (a 0xFD then a HEARTBEAT-like header, which completes
  // and fails its checksum), then a valid frame
  Encoder encoder(1, 1);
  const Bytes good = EncodeToVector(&encoder, Heartbeat{.custom_mode = 3, .mavlink_version = 3});
  Bytes tricky_payload(40, 0x00);
  tricky_payload[5] = kStartByte;
  tricky_payload[6] = 9;  // length 9, then zero flags and id 0 (HEARTBEAT)
  // numbered on after `good` (sequence 0) by the same sender, as a real link numbers them
  const Bytes a = RawFrame(33, 104, Bytes(28, 0x31), 1);  // GLOBAL_POSITION_INT-sized
  const Bytes b = RawFrame(245, 130, tricky_payload, 2);
  const Bytes c_frame = RawFrame(163, 163, Bytes(42, 0x07), 3);
  encoder.set_sequence(4);
  const Bytes next = EncodeToVector(&encoder, Heartbeat{.custom_mode = 3, .mavlink_version = 3});
  const Bytes stream = Concat({good, a, b, c_frame, next});
  // When it is parsed
  Parser parser;
  const auto got = ParseAll(&parser, stream);
  // Then both valid frames decode, the three unknown ones are skipped by their length, and
  // nothing counts as discarded or failed
  EXPECT_EQ(got.size(), 2U);
  const ParserCounters& c = parser.counters();
  EXPECT_EQ(c.unknown_frames, 3U);
  EXPECT_EQ(c.unknown_ids, 3U);
  EXPECT_EQ(c.bytes_in_unknown_frames, a.size() + b.size() + c_frame.size());
  EXPECT_EQ(c.bytes_discarded, 0U);
  EXPECT_EQ(c.crc_errors, 0U);
  EXPECT_EQ(c.bad_lengths, 0U);
  ExpectConservation(parser);
}

TEST(ParserTest, AnUnknownRunOutOfSequenceIsNotConfirmed) {
  // Given unknown frames that line up by length but not by sequence (or sender) before the
  // valid frame: what garbage could look like by chance
  Encoder encoder(1, 1);
  const Bytes good = EncodeToVector(&encoder, Heartbeat{.custom_mode = 3, .mavlink_version = 3});
  const Bytes a = RawFrame(33, 104, Bytes(28, 0x31), 1);
  const Bytes gap = RawFrame(245, 130, Bytes{0, 1}, 7);  // not 2
  encoder.set_sequence(8);
  const Bytes next = EncodeToVector(&encoder, Heartbeat{.custom_mode = 3, .mavlink_version = 3});
  encoder.set_sequence(1);  // the valid frame does not follow the run's last (7)
  const Bytes wrong = EncodeToVector(&encoder, Heartbeat{.custom_mode = 3, .mavlink_version = 3});
  Parser p1, p2;
  EXPECT_EQ(ParseAll(&p1, Concat({good, a, gap, next})).size(), 2U);
  EXPECT_EQ(ParseAll(&p2, Concat({good, a, gap, wrong})).size(), 2U);
  // Then the second frame starts a run of its own (confirmed by `next`), the first one stays
  // discarded; with `wrong` neither is confirmed
  EXPECT_EQ(p1.counters().unknown_frames, 1U);
  EXPECT_EQ(p1.counters().bytes_discarded, a.size());
  EXPECT_EQ(p2.counters().unknown_frames, 0U);
  EXPECT_EQ(p2.counters().bytes_discarded, a.size() + gap.size());
  ExpectConservation(p1);
  ExpectConservation(p2);
}

TEST(ParserTest, UnknownFramesEndingTheirDatagramAreConfirmedByItsEnd) {
  Encoder encoder(1, 1);
  const Bytes good = EncodeToVector(&encoder, Heartbeat{.custom_mode = 3, .mavlink_version = 3});
  const Bytes unknown = RawFrame(245, 130, Bytes{0, 1});
  Parser parser;
  ParseAll(&parser, Concat({good, unknown}));
  EXPECT_EQ(parser.counters().bytes_discarded, unknown.size());  // not yet known
  parser.EndOfDatagram();
  EXPECT_EQ(parser.counters().bytes_discarded, 0U);
  EXPECT_EQ(parser.counters().unknown_frames, 1U);
  // A false start byte inside the datagram's last unknown frame (still buffered at its end)
  // goes with it
  Bytes tricky(12, 0x00);
  tricky[9] = kStartByte;
  tricky[10] = 200;  // a false candidate claiming 200 payload bytes
  const Bytes last = RawFrame(245, 130, tricky, 1);
  Parser buffered;
  ParseAll(&buffered, Concat({good, last}));
  EXPECT_GT(buffered.buffered(), 0U);
  buffered.EndOfDatagram();
  EXPECT_EQ(buffered.buffered(), 0U);
  EXPECT_EQ(buffered.counters().unknown_frames, 1U);
  EXPECT_EQ(buffered.counters().bytes_discarded, 0U);
  ExpectConservation(buffered);
  // A datagram ending inside an unknown frame's declared length confirms nothing
  Parser cut;
  const Bytes partial(unknown.begin(), unknown.end() - 1);
  ParseAll(&cut, Concat({good, partial}));
  cut.EndOfDatagram();
  EXPECT_EQ(cut.counters().unknown_frames, 0U);
  ExpectConservation(parser);
  ExpectConservation(cut);
}

TEST(ParserTest, AnUnknownHeaderInGarbageNeverSwallowsTheValidFrameInsideItsDeclaredLength) {
  // Given a false start claiming an unknown id and 200 payload bytes, then a valid frame
  // well inside those 200 bytes
  Encoder encoder(1, 1);
  const Bytes good = EncodeToVector(&encoder, Heartbeat{.custom_mode = 5, .mavlink_version = 3});
  const Bytes false_header = {kStartByte, 200, 0x00, 0x00, 0x00, 1, 1, 0x21, 0x00, 0x00};
  const Bytes stream = Concat({false_header, Bytes(7, 0x55), good, Bytes(300, 0x66), good});
  Parser parser;
  const auto got = ParseAll(&parser, stream);
  // Then both valid frames decode and the garbage is discarded, not taken for a frame
  EXPECT_EQ(got.size(), 2U);
  EXPECT_EQ(parser.counters().unknown_frames, 0U);
  EXPECT_EQ(parser.counters().bytes_in_unknown_frames, 0U);
  EXPECT_EQ(parser.counters().bytes_discarded, false_header.size() + 7 + 300);
  ExpectConservation(parser);
}

TEST(ParserTest, ByteAtATimeAndChunksGiveTheSameFrames) {
  std::mt19937 rng(9);
  Encoder encoder(1, 1);
  Bytes stream;
  for (int i = 0; i < 50; ++i) {
    const Bytes f = EncodeToVector(&encoder, RandomMessage(&rng));
    stream.insert(stream.end(), f.begin(), f.end());
    stream.push_back(kStartByte);  // a lone start byte between frames
  }
  Parser one;
  const auto a = ParseAll(&one, stream);
  Parser chunks;
  std::vector<Received> b;
  for (std::size_t at = 0; at < stream.size();) {
    const std::size_t n = std::min<std::size_t>(rng() % 100, stream.size() - at);
    chunks.Parse(std::span(stream).subspan(at, n), [&](const Frame& f) {
      b.push_back({f.header, f.message, Bytes(f.bytes.begin(), f.bytes.end()), false});
    });
    at += n;
  }
  ASSERT_EQ(a.size(), 50U);
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i].bytes, b[i].bytes);
}

TEST(ParserTest, ResetDropsAnIncompleteFrame) {
  Encoder encoder(1, 1);
  const Bytes f = EncodeToVector(&encoder, Heartbeat{.custom_mode = 7, .mavlink_version = 3});
  Parser parser;
  ParseAll(&parser, Bytes(f.begin(), f.begin() + 8));
  EXPECT_EQ(parser.buffered(), 8U);
  parser.Reset();
  EXPECT_EQ(parser.buffered(), 0U);
  EXPECT_EQ(parser.counters().bytes_discarded, 8U);
  EXPECT_EQ(ParseAll(&parser, f).size(), 1U);
  ExpectConservation(parser);
}

}  // namespace
}  // namespace fnmpc::mavlink

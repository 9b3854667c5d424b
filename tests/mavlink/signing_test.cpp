// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/signing.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <vector>

#include "fnmpc/mavlink/crc.hpp"
#include "fnmpc/mavlink/encoder.hpp"
#include "fnmpc/mavlink/parser.hpp"
#include "tests/mavlink/sample_messages.hpp"

namespace fnmpc::mavlink {
namespace {

using testing::EncodeToVector;
using testing::TestKey;
using Bytes = std::vector<std::uint8_t>;

// Frames accepted when `stream` is fed to `parser`.
std::size_t Accepted(Parser* parser, const Bytes& stream) {
  std::size_t n = 0;
  parser->Parse(stream, [&](const Frame&) { ++n; });
  return n;
}

// A signed frame of `sender` (link `link`) at time `t`.
Bytes Signed(Encoder* sender, std::uint64_t t, const SigningKey& key, std::uint8_t link = 1) {
  sender->EnableSigning(key, link);
  sender->SetTimestamp(t);
  return EncodeToVector(sender, Heartbeat{.custom_mode = 5, .mavlink_version = 3});
}

TEST(SigningTest, KeyedParserAcceptsFramesSignedWithItsKey) {
  // Given a parser and a sender sharing a key
  Parser parser;
  parser.SetSigningKey(TestKey());
  Encoder sender(1, 1);
  // When signed frames with increasing timestamps arrive
  std::size_t n = 0;
  for (std::uint64_t t = 1000; t < 1010; ++t) n += Accepted(&parser, Signed(&sender, t, TestKey()));
  // Then all are accepted and expose their signature block
  EXPECT_EQ(n, 10U);
  EXPECT_EQ(parser.counters().signature_failures, 0U);
  Frame last;
  parser.Parse(Signed(&sender, 2000, TestKey(), 9), [&](const Frame& f) { last = f; });
  EXPECT_TRUE(last.is_signed);
  EXPECT_EQ(last.signature.link_id, 9);
  EXPECT_EQ(last.signature.timestamp, 2000U);
}

TEST(SigningTest, KeyedParserRejectsUnsignedWrongKeyAndTamperedFrames) {
  Parser parser;
  parser.SetSigningKey(TestKey());
  Encoder sender(1, 1);
  // Unsigned
  sender.DisableSigning();
  EXPECT_EQ(Accepted(&parser, EncodeToVector(&sender, Heartbeat{.mavlink_version = 3})), 0U);
  EXPECT_EQ(parser.counters().unsigned_rejected, 1U);
  // Signed with another key
  EXPECT_EQ(Accepted(&parser, Signed(&sender, 100, TestKey(1))), 0U);
  EXPECT_EQ(parser.counters().bad_signatures, 1U);
  // Right key, but one signature byte changed
  Bytes f = Signed(&sender, 101, TestKey());
  f.back() ^= 1;
  EXPECT_EQ(Accepted(&parser, f), 0U);
  // Right key, payload changed and the checksum recomputed: the signature no longer matches
  Bytes g = Signed(&sender, 102, TestKey());
  g[kHeaderLength] ^= 1;
  std::uint16_t crc = kCrcInit;
  for (std::size_t i = 1; i < kHeaderLength + g[1]; ++i) crc = CrcAccumulate(g[i], crc);
  crc = CrcAccumulate(Heartbeat::kCrcExtra, crc);
  g[kHeaderLength + g[1]] = crc & 0xFF;
  g[kHeaderLength + g[1] + 1] = crc >> 8;
  EXPECT_EQ(Accepted(&parser, g), 0U);
  // Right key, timestamp changed: the signature covers it
  Bytes h = Signed(&sender, 103, TestKey());
  h[kHeaderLength + h[1] + kChecksumLength + 1] ^= 1;
  EXPECT_EQ(Accepted(&parser, h), 0U);
  EXPECT_EQ(parser.counters().bad_signatures, 4U);
  EXPECT_EQ(parser.counters().signature_failures, 5U);
  EXPECT_EQ(parser.counters().frames_ok, 0U);
  // Still accepts a good one after all that
  EXPECT_EQ(Accepted(&parser, Signed(&sender, 104, TestKey())), 1U);
}

TEST(SigningTest, PayloadFramesAreNumberedTruncatedAndSignedLikeMessages) {
  // Given a signing sender that writes a HEARTBEAT, then an EXTENDED_SYS_STATE (245,
  // CRC_EXTRA 130) it has no struct for, then a HEARTBEAT
  Encoder sender(3, 1);
  sender.EnableSigning(TestKey(), 4);
  sender.SetTimestamp(5000);
  const Bytes first = EncodeToVector(&sender, Heartbeat{.mavlink_version = 3});
  std::array<std::uint8_t, kMaxFrameLength> out{};
  const std::array<std::uint8_t, 4> payload{0, 2, 0, 0};
  const std::size_t n = sender.EncodePayload(245, 130, payload, out);
  const Bytes third = EncodeToVector(&sender, Heartbeat{.mavlink_version = 3});
  // Then the payload frame is truncated to 2 bytes, signed, between the two in sequence and
  // timestamp, and its signature is the one of its bytes
  ASSERT_EQ(n, kHeaderLength + 2 + kChecksumLength + kSignatureLength);
  EXPECT_EQ(out[1], 2);
  EXPECT_EQ(out[2], kIncompatFlagSigned);
  EXPECT_EQ(out[4], static_cast<std::uint8_t>(first[4] + 1));
  EXPECT_EQ(third[4], static_cast<std::uint8_t>(first[4] + 2));
  const std::size_t sig_at = kHeaderLength + 2 + kChecksumLength;
  EXPECT_EQ(out[sig_at], 4);
  std::uint64_t timestamp = 0;
  for (int i = 5; i >= 0; --i) timestamp = (timestamp << 8) | out[sig_at + 1 + i];
  EXPECT_EQ(timestamp, 5001U);
  const auto signature =
      ComputeSignature(TestKey(), std::span<const std::uint8_t>(out.data(), sig_at), 4, timestamp);
  EXPECT_TRUE(std::equal(signature.begin(), signature.end(), out.begin() + sig_at + 7));
  // And a keyed parser still accepts the next HEARTBEAT after the unknown-id frame
  Parser parser;
  parser.SetSigningKey(TestKey());
  Bytes stream = first;
  stream.insert(stream.end(), out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n));
  stream.insert(stream.end(), third.begin(), third.end());
  EXPECT_EQ(Accepted(&parser, stream), 2U);
  EXPECT_EQ(parser.counters().unknown_frames, 1U);
  EXPECT_EQ(parser.counters().signature_failures, 0U);
}

TEST(SigningTest, TimestampsMustIncreasePerStream) {
  Parser parser;
  parser.SetSigningKey(TestKey());
  Encoder a(1, 1);
  Encoder b(2, 1);
  const Bytes first = Signed(&a, 5000, TestKey());
  EXPECT_EQ(Accepted(&parser, first), 1U);
  // A replay of the same frame, and an older timestamp of the same stream, are rejected
  EXPECT_EQ(Accepted(&parser, first), 0U);
  Encoder a_again(1, 1);  // (an encoder itself never goes back in time)
  EXPECT_EQ(Accepted(&parser, Signed(&a_again, 4999, TestKey())), 0U);
  EXPECT_EQ(parser.counters().timestamps_rejected, 2U);
  // Another link of the same sender, and another system, are other streams
  EXPECT_EQ(Accepted(&parser, Signed(&a, 4990, TestKey(), 2)), 1U);
  EXPECT_EQ(Accepted(&parser, Signed(&b, 4980, TestKey())), 1U);
  // A new stream more than one minute behind the newest timestamp is rejected, within it not
  Encoder c(3, 1);
  EXPECT_EQ(Accepted(&parser, Signed(&c, 100, TestKey())), 1U);  // 4900 behind: < 1 min
  parser.SetTimestamp(5000 + 2 * kNewStreamTimestampWindow);
  Encoder d(4, 1);
  EXPECT_EQ(Accepted(&parser, Signed(&d, 5000, TestKey())), 0U);
  EXPECT_EQ(Accepted(&parser, Signed(&d, 5000 + kNewStreamTimestampWindow, TestKey())), 1U);
  // A known stream only has to move forward
  EXPECT_EQ(Accepted(&parser, Signed(&a, 5001, TestKey())), 1U);
  EXPECT_EQ(parser.counters().timestamps_rejected, 3U);
}

TEST(SigningTest, ForgottenStreamsFallBackToTheNewStreamWindow) {
  // Given a full stream table: the first stream's frame, then kMaxSigningStreams newer ones
  Parser parser;
  parser.SetSigningKey(TestKey());
  const std::uint64_t t0 = 10 * kNewStreamTimestampWindow;
  Encoder first(200, 1);
  const Bytes old = Signed(&first, t0, TestKey());
  EXPECT_EQ(Accepted(&parser, old), 1U);
  std::vector<Bytes> later;
  for (std::uint8_t s = 1; s <= Parser::kMaxSigningStreams; ++s) {
    Encoder e(s, 1);
    later.push_back(Signed(&e, t0 + s, TestKey()));
    EXPECT_EQ(Accepted(&parser, later.back()), 1U);
  }
  // Then the oldest stream was forgotten: its replay is held to the new-stream window only,
  // which it passes (within a minute of the newest timestamp)
  EXPECT_EQ(Accepted(&parser, old), 1U);
  // and is then tracked again (forgetting stream 1): a second replay is rejected
  EXPECT_EQ(Accepted(&parser, old), 0U);
  // A minute later, a replay of the forgotten stream 1 fails the window
  parser.SetTimestamp(t0 + 2 * kNewStreamTimestampWindow);
  EXPECT_EQ(Accepted(&parser, later.front()), 0U);
  // while a replay of a tracked stream fails its own timestamp
  EXPECT_EQ(Accepted(&parser, later.back()), 0U);
  EXPECT_EQ(parser.counters().timestamps_rejected, 3U);
}

TEST(SigningTest, WithoutKeySignedFramesAreAcceptedAndClearingTheKeyAcceptsUnsigned) {
  Parser parser;
  Encoder sender(1, 1);
  EXPECT_EQ(Accepted(&parser, Signed(&sender, 1, TestKey(3))), 1U);
  parser.SetSigningKey(TestKey());
  sender.DisableSigning();
  const Bytes plain = EncodeToVector(&sender, Heartbeat{.mavlink_version = 3});
  EXPECT_EQ(Accepted(&parser, plain), 0U);
  parser.ClearSigningKey();
  EXPECT_FALSE(parser.signing());
  EXPECT_EQ(Accepted(&parser, plain), 1U);
}

}  // namespace
}  // namespace fnmpc::mavlink

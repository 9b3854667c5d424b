// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/signing.hpp"

#include <gtest/gtest.h>

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

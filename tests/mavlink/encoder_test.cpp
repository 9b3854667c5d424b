// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/encoder.hpp"

#include <gtest/gtest.h>

#include <array>
#include <vector>

#include "fnmpc/mavlink/crc.hpp"
#include "fnmpc/mavlink/sha256.hpp"
#include "fnmpc/mavlink/wire.hpp"
#include "tests/mavlink/sample_messages.hpp"

namespace fnmpc::mavlink {
namespace {

using testing::EncodeToVector;
using testing::TestKey;

// The checksum of a frame recomputed from its bytes: CRC over length .. payload, then extra.
std::uint16_t Checksum(const std::vector<std::uint8_t>& f, std::uint8_t crc_extra) {
  const std::size_t end = kHeaderLength + f[1];
  std::uint16_t crc = kCrcInit;
  for (std::size_t i = 1; i < end; ++i) crc = CrcAccumulate(f[i], crc);
  return CrcAccumulate(crc_extra, crc);
}

TEST(EncoderTest, HeartbeatFrameLayout) {
  // Given a sender 42/200 and a heartbeat
  Encoder encoder(42, 200);
  Heartbeat hb;
  hb.custom_mode = 0x11223344;
  hb.type = 2;        // MAV_TYPE_QUADROTOR
  hb.autopilot = 12;  // MAV_AUTOPILOT_PX4
  hb.base_mode = 0x81;
  hb.system_status = 4;
  hb.mavlink_version = 3;
  // When it is encoded
  const auto f = EncodeToVector(&encoder, hb);
  // Then the frame is: header, 9 payload bytes, checksum
  ASSERT_EQ(f.size(), kHeaderLength + 9 + kChecksumLength);
  const std::vector<std::uint8_t> header{0xFD, 9, 0, 0, 0, 42, 200, 0, 0, 0};
  EXPECT_EQ(std::vector<std::uint8_t>(f.begin(), f.begin() + 10), header);
  const std::vector<std::uint8_t> payload{0x44, 0x33, 0x22, 0x11, 2, 12, 0x81, 4, 3};
  EXPECT_EQ(std::vector<std::uint8_t>(f.begin() + 10, f.begin() + 19), payload);
  const std::uint16_t crc = Checksum(f, Heartbeat::kCrcExtra);
  EXPECT_EQ(f[19], crc & 0xFF);
  EXPECT_EQ(f[20], crc >> 8);
}

TEST(EncoderTest, MessageIdIsThreeBytesLittleEndian) {
  Encoder encoder(1, 1);
  const auto f = EncodeToVector(&encoder, Odometry{.time_usec = 1});
  EXPECT_EQ(f[7], 331 & 0xFF);
  EXPECT_EQ(f[8], 331 >> 8);
  EXPECT_EQ(f[9], 0);
}

TEST(EncoderTest, TruncatesTrailingZerosButKeepsTheFirstByte) {
  Encoder encoder(1, 1);
  // A COMMAND_ACK with only the command set: 0x0190 (400) is 0x90 0x01, result 0 trimmed
  const auto ack = EncodeToVector(&encoder, CommandAck{.command = 400});
  EXPECT_EQ(ack[1], 2);
  EXPECT_EQ(ack.size(), kHeaderLength + 2 + kChecksumLength);
  // An extension set keeps everything up to it
  const auto ack2 = EncodeToVector(&encoder, CommandAck{.command = 400, .target_system = 7});
  EXPECT_EQ(ack2[1], 9);
  // A zero message keeps one byte (the spec: the first byte is never truncated)
  const auto zero = EncodeToVector(&encoder, Attitude{});
  EXPECT_EQ(zero[1], 1);
  EXPECT_EQ(zero[10], 0);
  // A full message is not truncated
  const auto full = EncodeToVector(&encoder, Heartbeat{.mavlink_version = 3});
  EXPECT_EQ(full[1], 9);
  // The checksum covers the truncated payload
  EXPECT_EQ(zero[11] | (zero[12] << 8), Checksum(zero, Attitude::kCrcExtra));
}

TEST(EncoderTest, SequenceCountsAndWraps) {
  Encoder encoder(1, 1);
  encoder.set_sequence(254);
  EXPECT_EQ(EncodeToVector(&encoder, Heartbeat{})[4], 254);
  EXPECT_EQ(EncodeToVector(&encoder, Heartbeat{})[4], 255);
  EXPECT_EQ(EncodeToVector(&encoder, Heartbeat{})[4], 0);
  EXPECT_EQ(encoder.sequence(), 1);
}

TEST(EncoderTest, TooSmallBufferWritesNothingAndUsesNoSequenceNumber) {
  Encoder encoder(1, 1);
  std::array<std::uint8_t, 20> small{};
  EXPECT_EQ(encoder.Encode(Heartbeat{.custom_mode = 1, .mavlink_version = 3}, small), 0U);
  EXPECT_EQ(encoder.sequence(), 0);
  std::array<std::uint8_t, 21> exact{};
  EXPECT_EQ(encoder.Encode(Heartbeat{.custom_mode = 1, .mavlink_version = 3}, exact), 21U);
  EXPECT_EQ(encoder.sequence(), 1);
}

TEST(EncoderTest, WriteFrameRejectsWhatCannotBeAFrame) {
  std::array<std::uint8_t, kMaxFrameLength + 10> out{};
  std::array<std::uint8_t, 256> payload{};
  FrameSpec spec;
  EXPECT_EQ(WriteFrame(spec, payload, out), 0U);  // 256 payload bytes
  EXPECT_EQ(WriteFrame(spec, std::span(payload).first(255), out), 267U);
  spec.message_id = 1U << 24;
  EXPECT_EQ(WriteFrame(spec, std::span(payload).first(1), out), 0U);
  spec.message_id = (1U << 24) - 1;
  const SigningKey key = TestKey();
  spec.key = &key;
  spec.timestamp = kMaxSigningTimestamp + 1;
  EXPECT_EQ(WriteFrame(spec, std::span(payload).first(1), out), 0U);
  spec.timestamp = kMaxSigningTimestamp;
  EXPECT_EQ(WriteFrame(spec, std::span(payload).first(255), out), kMaxFrameLength);
}

TEST(EncoderTest, SignedFrameCarriesLinkTimestampAndSha256Signature) {
  // Given a signing encoder on link 7 at time 0x0000_0102_0304_0506
  Encoder encoder(3, 4);
  const SigningKey key = TestKey();
  encoder.EnableSigning(key, 7);
  encoder.SetTimestamp(0x010203040506ULL);
  // When it encodes a message
  const auto f = EncodeToVector(&encoder, LocalPositionNed{.time_boot_ms = 5, .x = 1.5F});
  // Then the signed flag is set and 13 bytes follow the checksum
  const std::size_t crc_end = kHeaderLength + f[1] + kChecksumLength;
  ASSERT_EQ(f.size(), crc_end + kSignatureLength);
  EXPECT_EQ(f[2], kIncompatFlagSigned);
  EXPECT_EQ(f[crc_end], 7);
  const std::vector<std::uint8_t> ts{0x06, 0x05, 0x04, 0x03, 0x02, 0x01};
  EXPECT_EQ(std::vector<std::uint8_t>(f.begin() + crc_end + 1, f.begin() + crc_end + 7), ts);
  // And the signature is SHA-256(key + frame through the link id and timestamp), 6 bytes
  std::vector<std::uint8_t> hashed(key.begin(), key.end());
  hashed.insert(hashed.end(), f.begin(), f.begin() + crc_end + 7);
  const Sha256Digest d = Sha256::Hash(hashed);
  EXPECT_EQ(std::vector<std::uint8_t>(f.begin() + crc_end + 7, f.end()),
            std::vector<std::uint8_t>(d.begin(), d.begin() + 6));
  // And the checksum covers the header with the signed flag
  EXPECT_EQ(f[crc_end - 2] | (f[crc_end - 1] << 8), Checksum(f, LocalPositionNed::kCrcExtra));
}

TEST(EncoderTest, SignatureTimestampsStrictlyIncrease) {
  Encoder encoder(1, 1);
  encoder.EnableSigning(TestKey(), 0);
  auto timestamp_of = [](const std::vector<std::uint8_t>& f) {
    return wire::GetUint(f.data() + kHeaderLength + f[1] + kChecksumLength + 1, 6);
  };
  encoder.SetTimestamp(100);
  EXPECT_EQ(timestamp_of(EncodeToVector(&encoder, Heartbeat{})), 100U);
  EXPECT_EQ(timestamp_of(EncodeToVector(&encoder, Heartbeat{})), 101U);  // clock stood still
  encoder.SetTimestamp(50);                                              // clock went back
  EXPECT_EQ(timestamp_of(EncodeToVector(&encoder, Heartbeat{})), 102U);
  encoder.SetTimestamp(500);
  EXPECT_EQ(timestamp_of(EncodeToVector(&encoder, Heartbeat{})), 500U);
  EXPECT_EQ(encoder.last_timestamp(), 500U);
  // Unsigned again: no signature block
  encoder.DisableSigning();
  const auto f = EncodeToVector(&encoder, Heartbeat{});
  EXPECT_EQ(f[2], 0);
  EXPECT_EQ(f.size(), kHeaderLength + 1 + kChecksumLength);
}

TEST(EncoderTest, SigningTimestampFromUnixTime) {
  EXPECT_EQ(SigningTimestampFromUnixUs(kSigningEpochUnixUs), 0U);
  EXPECT_EQ(SigningTimestampFromUnixUs(0), 0U);
  EXPECT_EQ(SigningTimestampFromUnixUs(kSigningEpochUnixUs + 1000000), 100000U);
  // 2025-01-01 00:00:00 UTC = 1735689600 s: 3653 days after the epoch
  EXPECT_EQ(SigningTimestampFromUnixUs(1735689600ULL * 1000000ULL), 3653ULL * 86400ULL * 100000ULL);
}

}  // namespace
}  // namespace fnmpc::mavlink

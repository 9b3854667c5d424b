// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/messages.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <random>

#include "fnmpc/mavlink/message.hpp"
#include "fnmpc/mavlink/message_layout.hpp"
#include "tests/mavlink/sample_messages.hpp"

namespace fnmpc::mavlink {
namespace {

using testing::RandomMessage;
using testing::SamePayload;

TEST(MessagesTest, TableListsEveryMessageWithItsConstants) {
  // Ids and lengths as in common.xml.
  const std::array<std::array<std::size_t, 3>, kNumMessages> expected{{{0, 9, 9},
                                                                       {1, 31, 43},
                                                                       {147, 36, 54},
                                                                       {30, 28, 28},
                                                                       {31, 32, 48},
                                                                       {32, 28, 28},
                                                                       {331, 230, 233},
                                                                       {105, 62, 63},
                                                                       {82, 39, 51},
                                                                       {83, 37, 37},
                                                                       {76, 33, 33},
                                                                       {77, 3, 10},
                                                                       {53100, 25, 25}}};
  ASSERT_EQ(SupportedMessages().size(), kNumMessages);
  for (std::size_t i = 0; i < kNumMessages; ++i) {
    const MessageInfo& info = SupportedMessages()[i];
    EXPECT_EQ(info.id, expected[i][0]);
    EXPECT_EQ(info.min_length, expected[i][1]) << info.name;
    EXPECT_EQ(info.max_length, expected[i][2]) << info.name;
    EXPECT_EQ(info.variant_index, i);
    EXPECT_EQ(FindMessageInfo(info.id), &info);
    EXPECT_EQ(info.dialect, info.id == 53100 ? "fnmpc" : "common") << info.name;
  }
  EXPECT_EQ(FindMessageInfo(24), nullptr);  // GPS_RAW_INT: not supported
  EXPECT_EQ(FindMessageInfo(1U << 23), nullptr);
}

TEST(MessagesTest, PackUnpackRoundTripOfEveryMessage) {
  std::mt19937 rng(11);
  for (std::size_t index = 0; index < kNumMessages; ++index) {
    for (int trial = 0; trial < 200; ++trial) {
      // Given a message with random fields
      const Message m = RandomMessage(index, &rng);
      // When it is packed and unpacked
      std::array<std::uint8_t, kMaxPayloadLength> payload{};
      const std::size_t n = PackPayload(m, payload);
      Message back;
      ASSERT_TRUE(UnpackPayload(InfoOf(m).id, std::span(payload).first(n), &back));
      // Then every field is back (floats are finite: == compares them exactly)
      EXPECT_EQ(n, InfoOf(m).max_length);
      EXPECT_EQ(back, m) << InfoOf(m).name;
      // And a payload cut after its last non-zero byte decodes to the same message
      const std::size_t cut = TruncatedPayloadLength(std::span(payload).first(n));
      Message from_truncated;
      ASSERT_TRUE(UnpackPayload(InfoOf(m).id, std::span(payload).first(cut), &from_truncated));
      EXPECT_EQ(from_truncated, m) << InfoOf(m).name;
    }
  }
}

TEST(MessagesTest, WireLayoutIsLittleEndianInSizeOrder) {
  // Given a HEARTBEAT and a COMMAND_ACK with distinct byte values
  Heartbeat hb;
  hb.custom_mode = 0x04030201;
  hb.type = 0x05;
  hb.autopilot = 0x06;
  hb.base_mode = 0x07;
  hb.system_status = 0x08;
  hb.mavlink_version = 0x09;
  std::array<std::uint8_t, Heartbeat::kMaxLength> p{};
  PackPayload(hb, std::span(p));
  // Then custom_mode (uint32) comes first, least significant byte first
  EXPECT_EQ(p, (std::array<std::uint8_t, 9>{1, 2, 3, 4, 5, 6, 7, 8, 9}));

  CommandAck ack;
  ack.command = 0x0201;
  ack.result = 3;
  ack.progress = 4;
  ack.result_param2 = -2;  // 0xFFFFFFFE
  ack.target_system = 9;
  ack.target_component = 10;
  std::array<std::uint8_t, CommandAck::kMaxLength> q{};
  PackPayload(ack, std::span(q));
  // Extensions in XML order after the base fields, not sorted by size
  EXPECT_EQ(q, (std::array<std::uint8_t, 10>{1, 2, 3, 4, 0xFE, 0xFF, 0xFF, 0xFF, 9, 10}));

  // A float is IEEE 754 binary32, little-endian.
  Attitude att;
  att.roll = 1.0F;  // 0x3F800000
  std::array<std::uint8_t, Attitude::kMaxLength> a{};
  PackPayload(att, std::span(a));
  EXPECT_EQ(a[4], 0x00);
  EXPECT_EQ(a[5], 0x00);
  EXPECT_EQ(a[6], 0x80);
  EXPECT_EQ(a[7], 0x3F);
}

TEST(MessagesTest, ShortPayloadReadsAsZeroExtendedAndExtraBytesAreIgnored) {
  // Given a SYS_STATUS payload without its extensions (a MAVLink 1 style sender)
  std::mt19937 rng(3);
  auto m = std::get<SysStatus>(RandomMessage(1, &rng, 0.0));
  std::array<std::uint8_t, kMaxPayloadLength> payload{};
  PackPayload(Message{m}, payload);
  Message back;
  ASSERT_TRUE(
      UnpackPayload(SysStatus::kId, std::span(payload).first(SysStatus::kMinLength), &back));
  // Then the base fields are read and the extensions are zero
  m.onboard_control_sensors_present_extended = 0;
  m.onboard_control_sensors_enabled_extended = 0;
  m.onboard_control_sensors_health_extended = 0;
  EXPECT_EQ(std::get<SysStatus>(back), m);
  // An empty payload is a zero message
  ASSERT_TRUE(UnpackPayload(SysStatus::kId, {}, &back));
  EXPECT_EQ(std::get<SysStatus>(back), SysStatus{});
  // Bytes beyond the max length are ignored
  payload.fill(0xAB);
  ASSERT_TRUE(UnpackPayload(Heartbeat::kId, payload, &back));
  EXPECT_EQ(std::get<Heartbeat>(back).custom_mode, 0xABABABABU);
  // An unsupported id leaves the message alone
  EXPECT_FALSE(UnpackPayload(24, payload, &back));
  EXPECT_TRUE(std::holds_alternative<Heartbeat>(back));
}

TEST(MessagesTest, NanFieldsSurviveBitForBit) {
  SetAttitudeTarget t;
  t.body_roll_rate = std::numeric_limits<float>::quiet_NaN();
  t.thrust_body = {std::numeric_limits<float>::infinity(), -0.0F, 1e-40F};  // denormal
  std::array<std::uint8_t, kMaxPayloadLength> payload{};
  const std::size_t n = PackPayload(Message{t}, payload);
  Message back;
  ASSERT_TRUE(UnpackPayload(SetAttitudeTarget::kId, std::span(payload).first(n), &back));
  EXPECT_TRUE(SamePayload(back, Message{t}));
  EXPECT_TRUE(std::isnan(std::get<SetAttitudeTarget>(back).body_roll_rate));
  EXPECT_TRUE(std::signbit(std::get<SetAttitudeTarget>(back).thrust_body[1]));
}

TEST(MessagesTest, TruncatedLengthKeepsTheFirstByte) {
  const std::array<std::uint8_t, 5> zeros{};
  EXPECT_EQ(TruncatedPayloadLength(zeros), 1U);
  const std::array<std::uint8_t, 5> tail{0, 7, 0, 0, 0};
  EXPECT_EQ(TruncatedPayloadLength(tail), 2U);
  const std::array<std::uint8_t, 3> full{1, 2, 3};
  EXPECT_EQ(TruncatedPayloadLength(full), 3U);
  EXPECT_EQ(TruncatedPayloadLength({}), 0U);
}

}  // namespace
}  // namespace fnmpc::mavlink

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/crc.hpp"

#include <gtest/gtest.h>

#include <array>
#include <string_view>

#include "fnmpc/mavlink/message.hpp"
#include "fnmpc/mavlink/message_layout.hpp"

namespace fnmpc::mavlink {
namespace {

TEST(CrcTest, CheckValueOfMcrf4xx) {
  // Given the catalogue check input of CRC-16/MCRF4XX
  constexpr std::string_view kCheck = "123456789";
  // Then its CRC is the catalogue's check value (also at compile time)
  static_assert(CrcAccumulate(std::string_view("123456789")) == 0x6F91);
  EXPECT_EQ(CrcAccumulate(kCheck), 0x6F91);
}

TEST(CrcTest, EmptyInputLeavesInitialValueAndBytesEqualText) {
  EXPECT_EQ(CrcAccumulate(std::span<const std::uint8_t>()), kCrcInit);
  constexpr std::array<std::uint8_t, 9> kBytes{'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(CrcAccumulate(kBytes), 0x6F91);
  // Accumulating in pieces equals accumulating at once.
  const std::uint16_t first = CrcAccumulate(std::span(kBytes).first(4));
  EXPECT_EQ(CrcAccumulate(std::span(kBytes).subspan(4), first), 0x6F91);
}

TEST(CrcTest, CrcExtraFromFieldListsMatchesCommonXml) {
  // The CRC_EXTRA of each message computed from our field list (name, types, names, array
  // lengths, wire order) equals the value mavgen publishes for common.xml.
  EXPECT_EQ(ComputeCrcExtra<Heartbeat>(), 50);
  EXPECT_EQ(ComputeCrcExtra<SysStatus>(), 124);
  EXPECT_EQ(ComputeCrcExtra<BatteryStatus>(), 154);
  EXPECT_EQ(ComputeCrcExtra<Attitude>(), 39);
  EXPECT_EQ(ComputeCrcExtra<AttitudeQuaternion>(), 246);
  EXPECT_EQ(ComputeCrcExtra<LocalPositionNed>(), 185);
  EXPECT_EQ(ComputeCrcExtra<Odometry>(), 91);
  EXPECT_EQ(ComputeCrcExtra<HighresImu>(), 93);
  EXPECT_EQ(ComputeCrcExtra<SetAttitudeTarget>(), 49);
  EXPECT_EQ(ComputeCrcExtra<AttitudeTarget>(), 22);
  EXPECT_EQ(ComputeCrcExtra<CommandLong>(), 152);
  EXPECT_EQ(ComputeCrcExtra<CommandAck>(), 143);
  // Our dialect's message: its CRC_EXTRA from "FNMPC_RELATIVE_OBSERVATION uint64_t time_usec
  // float range float bearing float elevation float relative_yaw uint8_t target_system ".
  EXPECT_EQ(ComputeCrcExtra<FnmpcRelativeObservation>(), 135);
  for (const MessageInfo& info : SupportedMessages()) {
    EXPECT_LE(info.min_length, info.max_length) << info.name;
  }
}

// HEARTBEAT with "system_state" for "system_status".
struct Misspelt : Heartbeat {
  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("custom_mode", m.custom_mode);
    v.Field("type", m.type);
    v.Field("autopilot", m.autopilot);
    v.Field("base_mode", m.base_mode);
    v.Field("system_state", m.system_status);
    v.Field("mavlink_version", m.mavlink_version);
  }
};

TEST(CrcTest, OneChangedFieldNameChangesCrcExtra) {
  // Given HEARTBEAT's field list with one name misspelt (Misspelt, above)
  // Then the computed CRC_EXTRA no longer matches
  EXPECT_NE(ComputeCrcExtra<Misspelt>(), Heartbeat::kCrcExtra);
  EXPECT_FALSE(LayoutMatches<Misspelt>());
}

}  // namespace
}  // namespace fnmpc::mavlink

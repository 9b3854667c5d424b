// SPDX-License-Identifier: BSD-3-Clause
// The generated ROS 2 message types: REP 2011 type hashes against the values ROS 2 generates,
// DDS type names of the ROS 2 conventions, the canonical type description, name resolution.
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "dds_node.hpp"
#include "fnmpc_ros2/msg_types.hpp"
#include "names.hpp"

namespace fnmpc::ros2 {
namespace {

// Values that ROS 2 Jazzy's rosidl generates (issue #53 for String and PoseStamped; the
// generated type-support sources of any Iron+ workspace for Time and Point).
TEST(TypeHash, MatchesRos2ForFlatAndNestedMessages) {
  EXPECT_STREQ(Ros2Type<std_msgs_msg_dds__String_>::kTypeHash,
               "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18");
  EXPECT_STREQ(Ros2Type<geometry_msgs_msg_dds__PoseStamped_>::kTypeHash,
               "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8");
  EXPECT_STREQ(Ros2Type<builtin_interfaces_msg_dds__Time_>::kTypeHash,
               "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197");
  EXPECT_STREQ(Ros2Type<geometry_msgs_msg_dds__Point_>::kTypeHash,
               "RIHS01_6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881");
}

TEST(TypeHash, CanonicalDescriptionOfString) {
  std::ifstream in(std::string(FNMPC_ROS2_IDL_DIR) + "/std_msgs/msg/String.json");
  ASSERT_TRUE(in) << "String.json not generated";
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(
      text.str(),
      "{\"type_description\": {\"type_name\": \"std_msgs/msg/String\", \"fields\": [{\"name\": "
      "\"data\", \"type\": {\"type_id\": 17, \"capacity\": 0, \"string_capacity\": 0, "
      "\"nested_type_name\": \"\"}}]}, \"referenced_type_descriptions\": []}\n");
}

TEST(TypeNames, FollowTheRos2DdsConvention) {
  EXPECT_STREQ(Ros2Type<nav_msgs_msg_dds__Odometry_>::kDdsName, "nav_msgs::msg::dds_::Odometry_");
  EXPECT_STREQ(Ros2Type<nav_msgs_msg_dds__Odometry_>::Descriptor()->m_typename,
               "nav_msgs::msg::dds_::Odometry_");
  EXPECT_STREQ(Ros2Type<fnmpc_msgs_msg_dds__ControllerStatus_>::kRosName,
               "fnmpc_msgs/msg/ControllerStatus");
  EXPECT_EQ(sensor_msgs_BatteryState_POWER_SUPPLY_STATUS_DISCHARGING, 2);
  // All the hashes differ (a hash computed from the wrong description would collide).
  EXPECT_STRNE(Ros2Type<geometry_msgs_msg_dds__Point_>::kTypeHash,
               Ros2Type<geometry_msgs_msg_dds__Vector3_>::kTypeHash);
  EXPECT_EQ(TypeHashUserData("RIHS01_ab"), "typehash=RIHS01_ab;");
}

TEST(Names, ResolveRelativeAbsolutePrivate) {
  EXPECT_EQ(ResolveName("/leader", "vehicle_node", "odom"), "/leader/odom");
  EXPECT_EQ(ResolveName("/leader", "vehicle_node", "/clock"), "/clock");
  EXPECT_EQ(ResolveName("/leader", "vehicle_node", "~/status"), "/leader/vehicle_node/status");
  EXPECT_EQ(ResolveName("", "sim", "clock"), "/clock");
  EXPECT_EQ(DdsTopicName("/leader/odom"), "rt/leader/odom");
}

TEST(Names, BadNamesAreRefusedWithTheRule) {
  auto message = [](const std::string& name) {
    try {
      ResolveName("/leader", "n", name);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("odom//x").find("empty token"), std::string::npos);
  EXPECT_NE(message("1odom").find("starts with a digit"), std::string::npos);
  EXPECT_NE(message("od-om").find("character '-'"), std::string::npos);
  EXPECT_NE(message("odom/").find("ends with '/'"), std::string::npos);
}

TEST(Names, Remapping) {
  Remappings r;
  r.Add("odom:=/ground_truth/odom");
  EXPECT_EQ(r.Apply("/leader", "n", "/leader/odom"), "/ground_truth/odom");
  EXPECT_EQ(r.Apply("/leader", "n", "/leader/imu"), "/leader/imu");
  EXPECT_THROW(r.Add("odom"), std::invalid_argument);
}

TEST(RosTime, RoundTripAndCarry) {
  const auto t = ToRosTime(12.25);
  EXPECT_EQ(t.sec, 12);
  EXPECT_EQ(t.nanosec, 250000000u);
  const auto carry = ToRosTime(0.9999999999);
  EXPECT_EQ(carry.sec, 1);
  EXPECT_EQ(carry.nanosec, 0u);
  EXPECT_DOUBLE_EQ(FromRosTime(ToRosTime(3.5)), 3.5);
}

}  // namespace
}  // namespace fnmpc::ros2

// SPDX-License-Identifier: BSD-3-Clause
// The DDS layer on Cyclone over loopback (the shipped configuration): a message goes through
// with its values, and the writer is discovered with the ROS 2 topic name, type name, QoS and
// USER_DATA type hash (read back from Cyclone's built-in publication topic, i.e. what a remote
// ROS 2 node learns in discovery). The independent check is fastdds_interop_test.
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "dds_node.hpp"

namespace fnmpc::ros2 {
namespace {

class DdsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    setenv("CYCLONEDDS_URI", "file://" FNMPC_ROS2_LOOPBACK_CONFIG, 1);
    setenv("ROS_DOMAIN_ID", "61", 1);
  }
};

// Waits (at most 10 s) for `done`; discovery takes a few hundred milliseconds on loopback.
template <typename F>
bool WaitFor(F done) {
  for (int i = 0; i < 1000; ++i) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

TEST_F(DdsTest, PoseStampedRoundTrip) {
  Participant participant;
  Writer<geometry_msgs_msg_dds__PoseStamped_> writer(participant, "rt/leader/pose",
                                                     QosProfile::Default());
  Reader<geometry_msgs_msg_dds__PoseStamped_> reader(participant, "rt/leader/pose",
                                                     QosProfile::Default());
  ASSERT_TRUE(WaitFor([&] { return writer.Subscriptions() == 1; }));
  geometry_msgs_msg_dds__PoseStamped_ out{};
  out.header.stamp = ToRosTime(4.5);
  out.header.frame_id = const_cast<char*>("world");
  out.pose.position = {1.0, -2.0, 3.5};
  out.pose.orientation = {0.0, 0.0, 0.6, 0.8};
  writer.Write(out);
  int received = 0;
  ASSERT_TRUE(WaitFor([&] {
    reader.TakeAll([&](const geometry_msgs_msg_dds__PoseStamped_& in) {
      ++received;
      EXPECT_EQ(in.header.stamp.sec, 4);
      EXPECT_EQ(in.header.stamp.nanosec, 500000000u);
      EXPECT_STREQ(in.header.frame_id, "world");
      EXPECT_EQ(in.pose.position.y, -2.0);
      EXPECT_EQ(in.pose.orientation.w, 0.8);
    });
    return received > 0;
  }));
  EXPECT_EQ(received, 1);
}

// The discovered publication of each profile.
TEST_F(DdsTest, DiscoveryShowsTheRos2Conventions) {
  Participant participant;
  Writer<nav_msgs_msg_dds__Odometry_> odom(participant, "rt/leader/odom", QosProfile::Default());
  Writer<sensor_msgs_msg_dds__Imu_> imu(participant, "rt/leader/imu", QosProfile::SensorData());
  const dds_entity_t builtin =
      dds_create_reader(participant.handle(), DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
  ASSERT_GT(builtin, 0);
  bool seen_odom = false;
  bool seen_imu = false;
  ASSERT_TRUE(WaitFor([&] {
    void* samples[8] = {};
    dds_sample_info_t info[8];
    const dds_return_t n = dds_read(builtin, samples, info, 8, 8);
    for (dds_return_t i = 0; i < n; ++i) {
      const auto* pub = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
      const std::string topic = pub->topic_name;
      dds_reliability_kind_t reliability;
      dds_duration_t blocking;
      EXPECT_TRUE(dds_qget_reliability(pub->qos, &reliability, &blocking));
      dds_history_kind_t history;
      int32_t depth = 0;
      EXPECT_TRUE(dds_qget_history(pub->qos, &history, &depth));
      dds_durability_kind_t durability;
      EXPECT_TRUE(dds_qget_durability(pub->qos, &durability));
      EXPECT_EQ(durability, DDS_DURABILITY_VOLATILE);
      void* user_data = nullptr;
      size_t size = 0;
      EXPECT_TRUE(dds_qget_userdata(pub->qos, &user_data, &size));
      const std::string user(static_cast<const char*>(user_data), size);
      dds_free(user_data);
      if (topic == "rt/leader/odom") {
        seen_odom = true;
        EXPECT_STREQ(pub->type_name, "nav_msgs::msg::dds_::Odometry_");
        EXPECT_EQ(reliability, DDS_RELIABILITY_RELIABLE);
        EXPECT_EQ(depth, 10);
        EXPECT_EQ(user, std::string("typehash=") +
                            Ros2Type<nav_msgs_msg_dds__Odometry_>::kTypeHash + ";");
      } else if (topic == "rt/leader/imu") {
        seen_imu = true;
        EXPECT_STREQ(pub->type_name, "sensor_msgs::msg::dds_::Imu_");
        EXPECT_EQ(reliability, DDS_RELIABILITY_BEST_EFFORT);
        EXPECT_EQ(depth, 5);
        EXPECT_EQ(user.rfind("typehash=RIHS01_", 0), 0u);
      }
    }
    if (n > 0) dds_return_loan(builtin, samples, n);
    return seen_odom && seen_imu;
  }));
}

TEST_F(DdsTest, BadDomainIsNamed) {
  setenv("ROS_DOMAIN_ID", "abc", 1);
  try {
    DomainIdFromEnvironment();
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ROS_DOMAIN_ID 'abc'"), std::string::npos);
  }
  setenv("ROS_DOMAIN_ID", "61", 1);
}

}  // namespace
}  // namespace fnmpc::ros2

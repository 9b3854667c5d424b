// SPDX-License-Identifier: BSD-3-Clause
// Against an independent DDS implementation: eProsima Fast DDS (Debian's libfastrtps 2.9), with
// the message layouts written here by hand from the ROS 2 conventions only (topic "rt/<name>",
// type "<pkg>::msg::dds_::<Name>_", plain CDR little-endian, the ROS 2 QoS profiles), i.e. what a
// ROS 2 node on rmw_fastrtps_cpp does. It shares no code with the Cyclone side but the test.
//  * Our Cyclone writers publish Odometry (default QoS), Imu (sensor data) and the fnmpc
//    attitude/thrust setpoint; Fast DDS discovers them with the right topic and type names,
//    reliability, durability and USER_DATA type hash, and receives the field values.
//  * A Fast DDS writer publishes a PoseStamped waypoint; our Cyclone reader receives it.

#include <array>
#include <chrono>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "dds_node.hpp"

#include "fastdds_types.hpp"

namespace {

using namespace fnmpc_fastdds_peer;
constexpr int kDomain = 62;

class FastDdsInterop : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    setenv("CYCLONEDDS_URI", "file://" FNMPC_ROS2_LOOPBACK_CONFIG, 1);
    setenv("ROS_DOMAIN_ID", std::to_string(kDomain).c_str(), 1);
  }
};

TEST_F(FastDdsInterop, FastDdsReceivesOurTopicsWithTheRos2Conventions) {
  using namespace fnmpc::ros2;
  Participant cyclone;
  Writer<nav_msgs_msg_dds__Odometry_> odom(cyclone, "rt/leader/odom", QosProfile::Default());
  Writer<sensor_msgs_msg_dds__Imu_> imu(cyclone, "rt/leader/imu", QosProfile::SensorData());
  Writer<fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_> setpoint(cyclone, "rt/leader/setpoint",
                                                               QosProfile::Default());
  FastDdsSide fast(kDomain);
  ASSERT_TRUE(fast.ok());
  auto* odom_reader = fast.Reader<Odometry>("rt/leader/odom", true, 10);
  auto* imu_reader = fast.Reader<Imu>("rt/leader/imu", false, 5);
  auto* setpoint_reader = fast.Reader<Setpoint>("rt/leader/setpoint", true, 10);
  ASSERT_TRUE(odom_reader && imu_reader && setpoint_reader);
  // Both sides' discovery: Cyclone matched the readers, Fast DDS reported the writers.
  ASSERT_TRUE(WaitFor([&] {
    std::lock_guard<std::mutex> lock(fast.listener.mutex);
    return odom.Subscriptions() == 1 && imu.Subscriptions() == 1 && setpoint.Subscriptions() == 1 &&
           fast.listener.writers.size() >= 3;
  })) << "Cyclone writers and Fast DDS readers did not discover each other";

  {
    std::lock_guard<std::mutex> lock(fast.listener.mutex);
    const auto& w = fast.listener.writers;
    ASSERT_EQ(w.count("rt/leader/odom"), 1u);
    EXPECT_EQ(w.at("rt/leader/odom").type, "nav_msgs::msg::dds_::Odometry_");
    EXPECT_TRUE(w.at("rt/leader/odom").reliable);
    EXPECT_TRUE(w.at("rt/leader/odom").volatile_durability);
    EXPECT_EQ(w.at("rt/leader/odom").user_data,
              std::string("typehash=") + Ros2Type<nav_msgs_msg_dds__Odometry_>::kTypeHash + ";");
    ASSERT_EQ(w.count("rt/leader/imu"), 1u);
    EXPECT_EQ(w.at("rt/leader/imu").type, "sensor_msgs::msg::dds_::Imu_");
    EXPECT_FALSE(w.at("rt/leader/imu").reliable);
    ASSERT_EQ(w.count("rt/leader/setpoint"), 1u);
    EXPECT_EQ(w.at("rt/leader/setpoint").type, "fnmpc_msgs::msg::dds_::AttitudeThrustSetpoint_");
  }

  nav_msgs_msg_dds__Odometry_ o{};
  o.header.stamp = ToRosTime(7.125);
  o.header.frame_id = const_cast<char*>("world");
  o.child_frame_id = const_cast<char*>("leader/base_link");
  o.pose.pose.position = {1.5, -0.25, 2.0};
  o.pose.pose.orientation = {0.0, 0.0, 0.6, 0.8};
  o.pose.covariance[35] = 0.01;
  o.twist.twist.linear = {0.5, 0.0, -0.1};
  o.twist.covariance[0] = 0.2;
  sensor_msgs_msg_dds__Imu_ i{};
  i.header.stamp = ToRosTime(7.13);
  i.header.frame_id = const_cast<char*>("leader/base_link");
  i.orientation.w = 1.0;
  i.orientation_covariance[0] = -1.0;  // ROS: orientation not provided
  i.angular_velocity = {0.01, -0.02, 0.3};
  i.linear_acceleration = {0.0, 0.1, 9.81};
  fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_ s{};
  s.header.stamp = ToRosTime(7.1);
  s.header.frame_id = const_cast<char*>("");
  s.thrust = 7.4;
  s.throttle = std::numeric_limits<double>::quiet_NaN();
  s.roll = 0.05;
  s.pitch = -0.04;
  s.yaw = 1.2;
  s.phase = const_cast<char*>("nmpc");

  Odometry got_odom;
  Imu got_imu;
  Setpoint got_setpoint;
  bool have_odom = false, have_imu = false, have_setpoint = false;
  // Best effort may drop a sample: publish until each arrived (bounded).
  ASSERT_TRUE(WaitFor([&] {
    if (!have_odom) odom.Write(o);
    if (!have_imu) imu.Write(i);
    if (!have_setpoint) setpoint.Write(s);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    have_odom = have_odom || TakeOne(odom_reader, &got_odom);
    have_imu = have_imu || TakeOne(imu_reader, &got_imu);
    have_setpoint = have_setpoint || TakeOne(setpoint_reader, &got_setpoint);
    return have_odom && have_imu && have_setpoint;
  }));
  EXPECT_EQ(got_odom.header.stamp.sec, 7);
  EXPECT_EQ(got_odom.header.stamp.nanosec, 125000000u);
  EXPECT_EQ(got_odom.header.frame_id, "world");
  EXPECT_EQ(got_odom.child_frame_id, "leader/base_link");
  EXPECT_EQ(got_odom.position.x, 1.5);
  EXPECT_EQ(got_odom.position.y, -0.25);
  EXPECT_EQ(got_odom.orientation.z, 0.6);
  EXPECT_EQ(got_odom.pose_covariance[35], 0.01);
  EXPECT_EQ(got_odom.linear.z, -0.1);
  EXPECT_EQ(got_odom.twist_covariance[0], 0.2);
  EXPECT_EQ(got_imu.header.frame_id, "leader/base_link");
  EXPECT_EQ(got_imu.orientation_covariance[0], -1.0);
  EXPECT_EQ(got_imu.angular_velocity.z, 0.3);
  EXPECT_EQ(got_imu.linear_acceleration.z, 9.81);
  EXPECT_EQ(got_setpoint.thrust, 7.4);
  EXPECT_TRUE(std::isnan(got_setpoint.throttle));
  EXPECT_EQ(got_setpoint.pitch, -0.04);
  EXPECT_EQ(got_setpoint.yaw, 1.2);
  EXPECT_EQ(got_setpoint.phase, "nmpc");
}

TEST_F(FastDdsInterop, OurReaderReceivesAFastDdsWaypoint) {
  using namespace fnmpc::ros2;
  Participant cyclone;
  Reader<geometry_msgs_msg_dds__PoseStamped_> reader(cyclone, "rt/leader/waypoint",
                                                     QosProfile::Default());
  FastDdsSide fast(kDomain);
  ASSERT_TRUE(fast.ok());
  auto* writer = fast.Writer<PoseStamped>("rt/leader/waypoint",
                                          Ros2Type<geometry_msgs_msg_dds__PoseStamped_>::kTypeHash);
  ASSERT_NE(writer, nullptr);
  // Both sides matched: a write before the Fast DDS writer knows our reader would be lost.
  ASSERT_TRUE(WaitFor([&] {
    fdds::PublicationMatchedStatus status;
    writer->get_publication_matched_status(status);
    return reader.Publications() == 1 && status.current_count == 1;
  })) << "Fast DDS writer and Cyclone reader did not discover each other";
  PoseStamped p;
  p.header.stamp = {12, 500};
  p.header.frame_id = "world";
  p.position = {3.0, 4.0, 1.25};
  p.orientation = {0.0, 0.0, 0.0, 1.0};
  ASSERT_TRUE(writer->write(&p));
  int received = 0;
  ASSERT_TRUE(WaitFor([&] {
    reader.TakeAll([&](const geometry_msgs_msg_dds__PoseStamped_& m) {
      ++received;
      EXPECT_EQ(m.header.stamp.sec, 12);
      EXPECT_EQ(m.header.stamp.nanosec, 500u);
      EXPECT_STREQ(m.header.frame_id, "world");
      EXPECT_EQ(m.pose.position.x, 3.0);
      EXPECT_EQ(m.pose.position.y, 4.0);
      EXPECT_EQ(m.pose.position.z, 1.25);
      EXPECT_EQ(m.pose.orientation.w, 1.0);
    });
    return received > 0;
  }));
  EXPECT_EQ(received, 1);
}

}  // namespace

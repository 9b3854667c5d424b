// SPDX-License-Identifier: BSD-3-Clause
// The nodes' parameters (ROS 2 command line and parameter file layout) and conversions.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "conversions.hpp"
#include "parameters.hpp"

namespace fnmpc::ros2 {
namespace {

std::string WriteFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

std::string ErrorOf(const std::vector<std::string>& args) {
  try {
    NodeOptions::Parse(args, "vehicle_node");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

TEST(NodeOptions, SectionsApplyInOrderAndDashPLast) {
  const std::string file = WriteFile("params.yaml",
                                     "/**:\n  ros__parameters:\n    lockstep: true\n    seed: 3\n"
                                     "/leader/vehicle_node:\n  ros__parameters:\n    seed: 5\n"
                                     "/follower1/vehicle_node:\n  ros__parameters:\n    seed: 9\n");
  const NodeOptions o = NodeOptions::Parse({"--ros-args", "-r", "__ns:=/leader", "--params-file",
                                            file, "-p", "scenario:=a.yaml", "-r", "odom:=/x/odom"},
                                           "vehicle_node");
  EXPECT_EQ(o.fully_qualified_name(), "/leader/vehicle_node");
  EXPECT_TRUE(o.Bool("lockstep", false));
  EXPECT_EQ(o.Int("seed", -1), 5);  // the node's own section after /**
  EXPECT_EQ(o.RequiredString("scenario"), "a.yaml");
  EXPECT_DOUBLE_EQ(o.Double("vehicle_timeout", 2.5), 2.5);
  EXPECT_EQ(o.Topic("imu"), "rt/leader/imu");
  EXPECT_EQ(o.Topic("odom"), "rt/x/odom");
  EXPECT_EQ(o.Topic("/clock"), "rt/clock");
}

TEST(NodeOptions, ErrorsNameTheFileLineAndParameter) {
  const std::string bad_type =
      WriteFile("bad_type.yaml", "/**:\n  ros__parameters:\n    seed: many\n");
  const NodeOptions o =
      NodeOptions::Parse({"--ros-args", "--params-file", bad_type}, "vehicle_node");
  try {
    o.Int("seed", 0);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "bad_type.yaml:3: parameter seed of /vehicle_node: expected an integer"),
              std::string::npos)
        << e.what();
  }
  const std::string no_params = WriteFile("no_params.yaml", "/**:\n  seed: 1\n");
  EXPECT_NE(ErrorOf({"--ros-args", "--params-file", no_params})
                .find("no_params.yaml:1: node '/**': expected a "
                      "ros__parameters map"),
            std::string::npos);
  EXPECT_NE(ErrorOf({"--ros-args", "-x"}).find("argument '-x': unknown"), std::string::npos);
  EXPECT_NE(ErrorOf({"--ros-args", "-p", "seed"}).find("expected name:=value"), std::string::npos);
  EXPECT_NE(ErrorOf({"seed"}).find("expected --ros-args first"), std::string::npos);
  EXPECT_NE(ErrorOf({"--ros-args", "--params-file"}).find("missing its value"), std::string::npos);
  const NodeOptions none = NodeOptions::Parse({}, "sim");
  EXPECT_THROW(none.RequiredString("scenario"), std::invalid_argument);
}

TEST(Conversions, MeasurementsRoundTrip) {
  Measurement m;
  m.kind = SensorKind::kMocapPose;
  m.stamp = 3.25;
  m.position = Vec3(1.0, -2.0, 0.5);
  m.euler = Vec3(0.1, -0.05, 1.2);
  const Measurement back = FromPose(ToPose(m), 2);
  EXPECT_EQ(back.kind, SensorKind::kMocapPose);
  EXPECT_EQ(back.vehicle, 2);
  EXPECT_DOUBLE_EQ(back.stamp, 3.25);
  EXPECT_TRUE(back.position.isApprox(m.position));
  EXPECT_LT((back.euler - m.euler).norm(), 1e-12);

  Measurement r;
  r.kind = SensorKind::kRelative;
  r.stamp = 1.0;
  r.relative.target = 1;
  r.relative.range = 2.5;
  r.relative.bearing = -0.3;
  r.relative.elevation = 0.1;
  r.relative.relative_yaw = 0.02;
  const auto msg = ToRelative(r, "follower1/base_link");
  EXPECT_STREQ(msg.header.frame_id, "follower1/base_link");
  const Measurement rb = FromRelative(msg, 0);
  EXPECT_EQ(rb.relative.target, 1);
  EXPECT_EQ(rb.relative.bearing, -0.3);
}

TEST(Conversions, OdometryTwistIsInTheBodyFrame) {
  const Vec3 euler(0.0, 0.0, M_PI / 2);  // facing +y
  const auto o = ToOdometry(2.0, "world", "leader/base_link", Vec3(1, 2, 3), Vec3(0, 1, 0), euler,
                            Vec3::Zero());
  EXPECT_NEAR(o.twist.twist.linear.x, 1.0, 1e-12);  // forward
  EXPECT_NEAR(o.twist.twist.linear.y, 0.0, 1e-12);
  Vec3 p, v, e;
  FromOdometry(o, &p, &v, &e);
  EXPECT_TRUE(v.isApprox(Vec3(0, 1, 0)));
  EXPECT_NEAR(e.z(), M_PI / 2, 1e-12);
}

}  // namespace
}  // namespace fnmpc::ros2

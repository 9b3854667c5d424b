// SPDX-License-Identifier: BSD-3-Clause
// The scenario's `faults:` block maps onto config::ScenarioFaults; bad values name the file,
// line and key.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "fnmpc/config/scenario_yaml.hpp"
#include "scenario_text.hpp"

namespace fnmpc::config {
namespace {

std::string Triangle() { return test::ShippedScenarioText("triangle.yaml"); }

ScenarioConfig Parse(const std::string& faults) {
  return ParseScenario(YamlMap::LoadString(Triangle() + faults, "s.yaml"));
}

std::string ErrorOf(const std::string& faults) {
  try {
    Parse(faults);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ScenarioFaultsYamlTest, AbsentMeansNoFault) {
  const ScenarioConfig s = Parse("");
  EXPECT_FALSE(s.faults.any());
  EXPECT_FALSE(s.faults.kill_controller.active());
  EXPECT_FALSE(s.faults.motors_off.active());
  EXPECT_TRUE(s.faults.sensor_dropouts.empty());
  EXPECT_EQ(s.faults.outlier_rate, 0.0);
  EXPECT_EQ(s.faults.solver_failure_rate, 0.0);
}

TEST(ScenarioFaultsYamlTest, EveryKeyMapped) {
  const ScenarioConfig s = Parse(
      "faults:\n"
      "  kill_controller: {vehicle: follower2, time: 27.5}\n"
      "  motors_off: {vehicle: follower1, time: 40}\n"
      "  sensor_dropouts:\n"
      "    - {vehicle: leader, sensor: mocap, from: 20, to: 22.5}\n"
      "    - {vehicle: follower1, sensor: relative, from: 30, to: 31}\n"
      "    - {vehicle: follower2, sensor: optical_flow, from: 0, to: 100}\n"
      "  outliers: {rate: 0.01, size: 0.5}\n"
      "  solver_failures: {rate: 0.2}\n");
  const ScenarioFaults& f = s.faults;
  EXPECT_TRUE(f.any());
  EXPECT_EQ(f.kill_controller.vehicle, "follower2");
  EXPECT_EQ(f.kill_controller.index, 2);
  EXPECT_DOUBLE_EQ(f.kill_controller.time, 27.5);
  EXPECT_EQ(f.motors_off.index, 1);
  EXPECT_DOUBLE_EQ(f.motors_off.time, 40.0);
  ASSERT_EQ(f.sensor_dropouts.size(), 3U);
  EXPECT_EQ(f.sensor_dropouts[0].index, 0);
  EXPECT_EQ(f.sensor_dropouts[0].sensor, SensorKind::kMocapPose);
  EXPECT_DOUBLE_EQ(f.sensor_dropouts[0].from, 20.0);
  EXPECT_DOUBLE_EQ(f.sensor_dropouts[0].to, 22.5);
  EXPECT_EQ(f.sensor_dropouts[1].sensor, SensorKind::kRelative);
  EXPECT_EQ(f.sensor_dropouts[2].sensor, SensorKind::kOpticalFlow);
  EXPECT_EQ(f.sensor_dropouts[2].index, 2);
  EXPECT_DOUBLE_EQ(f.outlier_rate, 0.01);
  EXPECT_DOUBLE_EQ(f.outlier_size, 0.5);
  EXPECT_DOUBLE_EQ(f.solver_failure_rate, 0.2);
}

TEST(ScenarioFaultsYamlTest, EachSensorNameIsAccepted) {
  for (const std::string name :
       {"mocap", "imu", "optical_flow", "compass", "battery", "relative"}) {
    const ScenarioConfig s =
        Parse("faults:\n  sensor_dropouts:\n    - {vehicle: leader, sensor: " + name +
              ", from: 1, to: 2}\n");
    ASSERT_EQ(s.faults.sensor_dropouts.size(), 1U);
    EXPECT_EQ(ToString(s.faults.sensor_dropouts[0].sensor), name);
  }
}

/// The error names the file, a line and the key.
void ExpectError(const std::string& faults, const std::string& key, int line) {
  const std::string e = ErrorOf(faults);
  ASSERT_FALSE(e.empty()) << "accepted:\n" << faults;
  EXPECT_NE(e.find("s.yaml:" + std::to_string(line) + ":"), std::string::npos) << e;
  EXPECT_NE(e.find(key), std::string::npos) << e;
}

TEST(ScenarioFaultsYamlTest, BadValuesNameFileLineAndKey) {
  // The faults block starts right after the triangle's last line.
  const std::string base = Triangle();
  const int first = static_cast<int>(std::count(base.begin(), base.end(), '\n')) + 2;
  ExpectError("faults:\n  kill_controller: {vehicle: follower3, time: 20}\n", "vehicle", first);
  ExpectError("faults:\n  kill_controller: {vehicle: follower1, time: -1}\n", "time", first);
  ExpectError("faults:\n  kill_controller: {vehicle: follower1, time: 200}\n", "time", first);
  ExpectError("faults:\n  kill_controller: {vehicle: follower1}\n", "time", first);
  ExpectError("faults:\n  motors_off: {vehicle: leader, time: .nan}\n", "time", first);
  ExpectError("faults:\n  motors_off: {vehicle: leader, time: 10, when: 3}\n", "when", first);
  ExpectError("faults:\n  sensor_dropouts:\n    - {vehicle: leader, sensor: gps, from: 1, to: 2}\n",
              "sensor", first + 1);
  ExpectError("faults:\n  sensor_dropouts:\n    - {vehicle: leader, sensor: imu, from: 3, to: 2}\n",
              "to", first + 1);
  ExpectError("faults:\n  sensor_dropouts:\n    - {vehicle: leader, sensor: imu, to: 2}\n", "from",
              first + 1);
  ExpectError("faults:\n  outliers: {rate: 1.5, size: 1}\n", "rate", first);
  ExpectError("faults:\n  outliers: {rate: 0.1, size: 0}\n", "size", first);
  ExpectError("faults:\n  outliers: {rate: 0.1}\n", "size", first);
  ExpectError("faults:\n  solver_failures: {rate: -0.1}\n", "solver_failures.rate", first);
  ExpectError("faults:\n  solver_failure: {rate: 0.1}\n", "solver_failure", first);  // misspelt
}

TEST(ScenarioFaultsYamlTest, ManualLeaderHasNoControllerToKill) {
  const std::string text = test::ShippedScenarioText("manual-leader.yaml");
  try {
    ParseScenario(YamlMap::LoadString(
        text + "faults:\n  kill_controller: {vehicle: leader, time: 20}\n", "m.yaml"));
    ADD_FAILURE() << "killing the manual leader's controller was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("kill_controller"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fnmpc::config

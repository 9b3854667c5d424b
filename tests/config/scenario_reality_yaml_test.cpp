// SPDX-License-Identifier: BSD-3-Clause
// The scenario's `reality:` block maps onto config::ScenarioReality; bad values name the file,
// line and key.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "fnmpc/config/scenario_yaml.hpp"
#include "scenario_text.hpp"

namespace fnmpc::config {
namespace {

/// The shipped scenario `name` without its `reality:` line (the shipped reference scenarios
/// fly with reality on), plus `extra`.
ScenarioConfig Parse(const std::string& name, const std::string& extra) {
  std::string text = test::ShippedScenarioText(name);
  const std::size_t at = text.find("\nreality:");
  if (at != std::string::npos) text.erase(at + 1, text.find('\n', at + 1) - at);
  return ParseScenario(YamlMap::LoadString(text + extra, "s.yaml"));
}

ScenarioConfig Shipped(const std::string& name) {
  return ParseScenario(YamlMap::LoadString(test::ShippedScenarioText(name), "s.yaml"));
}

std::string ErrorOf(const std::string& extra) {
  try {
    Parse("triangle.yaml", extra);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ScenarioRealityYamlTest, AbsentIsOffAndAnEmptyBlockIsOnWithTheDefaults) {
  EXPECT_FALSE(Parse("triangle.yaml", "").reality.enabled);
  const ScenarioConfig s = Parse("triangle.yaml", "reality: {}\n");
  EXPECT_TRUE(s.reality.enabled);
  EXPECT_TRUE(s.reality.rotor_aerodynamics);
  EXPECT_TRUE(s.reality.wake);
  EXPECT_TRUE(s.reality.sensors);
  EXPECT_EQ(s.reality.plant.mass, model::PlantSpread{}.mass);
}

TEST(ScenarioRealityYamlTest, EveryShippedScenarioFliesWithRealityOn) {
  for (const char* name : {"triangle.yaml", "manual-leader.yaml", "follower-below-leader.yaml",
                           "flying-leader-paper.yaml"}) {
    const ScenarioConfig s = Shipped(name);
    EXPECT_TRUE(s.reality.enabled) << name;
    EXPECT_TRUE(s.reality.rotor_aerodynamics && s.reality.wake && s.reality.sensors) << name;
  }
}

TEST(ScenarioRealityYamlTest, EveryKeyMapped) {
  const ScenarioConfig s = Parse("triangle.yaml", R"(reality:
  enabled: true
  rotor_aerodynamics: false
  wake: false
  sensors: false
  sensor_models: {accel_bias: 0.1, burst_share: 0.02, burst_length: 0.3, mocap_outlier_rate: 0.01, autopilot_estimate: false}
  plant: {mass: 0.05, inertia: 0.2, thrust_constant: 0.01, torque_constant: 0.02, motor_time_constant: 0.1, thrust_scale: 0.04, voltage_dependence: 0.2, voltage_reference: 14.0, attitude_bias_deg: [1.0, 3.0], attitude_gains: 0.05}
  wind:
    velocity: [1.0, 2.0, 0.0]
    gusts: {std: 0.3, time_constant: 1.5}
    turbulence: {w20: 5.0, height: 10.0}
    discrete_gusts:
      - {time: 20.0, duration: 2.0, amplitude: [0.0, 1.0, 0.0]}
)");
  const ScenarioReality& r = s.reality;
  EXPECT_FALSE(r.rotor_aerodynamics || r.wake || r.sensors);
  EXPECT_EQ(r.sensor_models.accel_bias, 0.1);
  EXPECT_EQ(r.sensor_models.burst_share, 0.02);
  EXPECT_EQ(r.sensor_models.burst_length, 0.3);
  EXPECT_EQ(r.sensor_models.mocap_outlier_rate, 0.01);
  EXPECT_FALSE(r.sensor_models.autopilot_estimate);
  EXPECT_EQ(r.plant.mass, 0.05);
  EXPECT_EQ(r.plant.inertia, 0.2);
  EXPECT_EQ(r.plant.voltage_reference, 14.0);
  EXPECT_NEAR(r.plant.attitude_bias_max, 3.0 * M_PI / 180.0, 1e-15);
  EXPECT_EQ(r.wind.velocity, Vec3(1.0, 2.0, 0.0));
  EXPECT_EQ(r.wind.gust_std, 0.3);
  EXPECT_EQ(r.wind.gust_time_constant, 1.5);
  EXPECT_EQ(r.turbulence.w20, 5.0);
  EXPECT_EQ(r.turbulence.height, 10.0);
  ASSERT_EQ(r.wind.discrete_gusts.size(), 1u);
  EXPECT_EQ(r.wind.discrete_gusts[0].start, 20.0);
  EXPECT_EQ(r.wind.discrete_gusts[0].duration, 2.0);
  EXPECT_EQ(r.wind.discrete_gusts[0].amplitude, Vec3(0.0, 1.0, 0.0));
}

TEST(ScenarioRealityYamlTest, BadValuesNameFileLineAndKey) {
  const std::string spread = ErrorOf("reality:\n  plant: {mass: 0.5}\n");
  EXPECT_NE(spread.find("s.yaml:"), std::string::npos) << spread;
  EXPECT_NE(spread.find("mass"), std::string::npos) << spread;
  EXPECT_NE(ErrorOf("reality:\n  wind: {turbulence: {w20: 5.0, height: 1.0}}\n").find("height"),
            std::string::npos);
  EXPECT_NE(ErrorOf("reality:\n  wind: {turbulence: {sigma: [1, 1, 1]}}\n").find("airspeed"),
            std::string::npos);
  EXPECT_NE(ErrorOf("reality:\n  colour: red\n").find("colour"), std::string::npos);
}

TEST(ScenarioRealityYamlTest, PlantFileGivesTheVehicleItsExplicitTruePlant) {
  std::string text = test::ShippedScenarioText("triangle.yaml");
  const std::string anchor = "  - name: follower1              # behind-left of the leader\n";
  const std::size_t at = text.find(anchor);
  ASSERT_NE(at, std::string::npos);
  text.insert(at + anchor.size(), "    plant_file: " + std::string(FNMPC_SOURCE_DIR) +
                                      "/config/vehicles/storm-drone-4.yaml\n"
                                      "    plant_motor_time_constant: 0.03\n");
  const ScenarioConfig s = ParseScenario(YamlMap::LoadString(text, "s.yaml"));
  EXPECT_TRUE(s.vehicles[1].has_plant);
  EXPECT_FALSE(s.vehicles[0].has_plant);
  EXPECT_EQ(s.vehicles[1].plant_motor_time_constant, 0.03);
  EXPECT_EQ(s.vehicles[1].plant.mass, s.vehicles[1].params.mass);
}

}  // namespace
}  // namespace fnmpc::config

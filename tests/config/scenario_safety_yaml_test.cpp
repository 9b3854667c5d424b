// SPDX-License-Identifier: BSD-3-Clause
// The scenario's `safety:` block maps onto formation::SafetyConfig; bad values name the
// file, line and key.
#include <gtest/gtest.h>

#include <string>

#include "fnmpc/config/scenario_yaml.hpp"
#include "scenario_text.hpp"

namespace fnmpc::config {
namespace {

std::string Triangle() { return test::ShippedScenarioText("triangle.yaml"); }

TEST(ScenarioSafetyYamlTest, DefaultsAndEveryKeyMapped) {
  const ScenarioConfig d = ParseScenario(YamlMap::LoadString(Triangle(), "s.yaml"));
  EXPECT_EQ(d.safety.recovery.fallbacks_before_reinit,
            formation::RecoveryConfig{}.fallbacks_before_reinit);
  const ScenarioConfig s = ParseScenario(YamlMap::LoadString(
      Triangle() + "safety:\n  min_altitude: 0.4\n  max_altitude: 4.0\n  neighbour_timeout: 2.0\n"
                   "  neighbour_reacquire_time: 0.25\n  recovery:\n    fallbacks_before_reinit: 5\n"
                   "    max_reinitialisations: 1\n    estimate_timeout: 0.7\n"
                   "    failsafe_hold_time: 2.5\n    failsafe_descent_speed: 0.6\n",
      "s.yaml"));
  EXPECT_DOUBLE_EQ(s.safety.min_altitude, 0.4);
  EXPECT_DOUBLE_EQ(s.safety.max_altitude, 4.0);
  EXPECT_DOUBLE_EQ(s.safety.neighbour_timeout, 2.0);
  EXPECT_DOUBLE_EQ(s.safety.neighbour_reacquire_time, 0.25);
  EXPECT_EQ(s.safety.recovery.fallbacks_before_reinit, 5);
  EXPECT_EQ(s.safety.recovery.max_reinitialisations, 1);
  EXPECT_DOUBLE_EQ(s.safety.recovery.estimate_timeout, 0.7);
  EXPECT_DOUBLE_EQ(s.safety.recovery.failsafe_hold_time, 2.5);
  EXPECT_DOUBLE_EQ(s.safety.recovery.failsafe_descent_speed, 0.6);
  EXPECT_NO_THROW(s.safety.Validate());
}

std::string ErrorOf(const std::string& safety_block) {
  try {
    ParseScenario(YamlMap::LoadString(Triangle() + safety_block, "s.yaml"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ScenarioSafetyYamlTest, BadValuesNameFileLineAndKey) {
  const std::string e1 = ErrorOf("safety:\n  max_altitude: 0.2\n");
  EXPECT_NE(e1.find("s.yaml:"), std::string::npos) << e1;
  EXPECT_NE(e1.find("max_altitude"), std::string::npos) << e1;
  const std::string e2 = ErrorOf("safety:\n  recovery:\n    fallbacks_before_reinit: 0\n");
  EXPECT_NE(e2.find("fallbacks_before_reinit"), std::string::npos) << e2;
  const std::string e3 = ErrorOf("safety:\n  recovery:\n    failsafe_descent_speed: 3\n");
  EXPECT_NE(e3.find("failsafe_descent_speed"), std::string::npos) << e3;
  const std::string e4 = ErrorOf("safety:\n  neighbour_timout: 1\n");  // misspelt
  EXPECT_NE(e4.find("neighbour_timout"), std::string::npos) << e4;
  const std::string e5 = ErrorOf("safety:\n  neighbour_timeout: .nan\n");
  EXPECT_NE(e5.find("neighbour_timeout"), std::string::npos) << e5;
}

}  // namespace
}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
// A shortened triangle scenario (take-off, one leader leg and its hold, landing) and the
// followers' swap (config/scenarios/stress/swap.yaml) run end to end in the MuJoCo simulator
// with every sensor and estimator in the loop.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {
namespace {

TEST(FormationFlightTest, ShortTriangleKeepsFormationAndLands) {
  // Given the shipped triangle scenario, shortened to 30 s of simulated time
  config::ScenarioConfig sc =
      config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/triangle.yaml");
  sc.trajectory_start = 8.0;
  sc = Shortened(sc, 30.0);
  const std::string dir =
      testing::TempDir() + "/fnmpc-integration-triangle-" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  // When it runs in closed loop
  RunOptions o;
  o.seed = 3;
  const nlohmann::json s = RunScenario(sc, o, dir);
  // Then the followers hold the formation in steady state within the reference's 0.05 m
  ASSERT_TRUE(s["steady_state_formation_error_m"].is_number()) << s.dump(2);
  EXPECT_LE(s["steady_state_formation_error_m"].get<double>(), 0.05) << s.dump(2);
  EXPECT_LT(s["max_formation_error_m"].get<double>(), 0.5);
  // and the solver never fell back, every vehicle landed gently, nobody came close
  EXPECT_EQ(s["fallbacks"].get<long>(), 0);
  EXPECT_EQ(s["solver_failures"].get<long>(), 0);
  EXPECT_EQ(s["guarded_commands"].get<long>(), 0);
  EXPECT_TRUE(s["landed_safely"].get<bool>()) << s.dump(2);
  // and nothing counts as a failure (docs/failure.md: envelope, take-off, landing, failsafe).
  EXPECT_TRUE(s["complete"].get<bool>());
  EXPECT_TRUE(s["failures"].empty()) << s["failures"].dump(2);
  EXPECT_GT(s["min_separation_m"].get<double>(), 1.5);
  EXPECT_TRUE(std::filesystem::exists(dir + "/follower1.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/summary.json"));
}

nlohmann::json FlySwap(double confidence) {
  config::ScenarioConfig sc = config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) +
                                                       "/config/scenarios/stress/swap.yaml");
  sc.safety.collision_confidence = confidence;
  // The chance constraint's margin alone: the tie-disagreement discount also keeps this seed
  // apart (0.567 m without the margin), so it is off in both flights.
  sc.tie_disagreement = 0.0;
  const std::string dir =
      testing::TempDir() + "/fnmpc-integration-swap-" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  RunOptions o;
  o.seed = 3;  // the seed whose swap came within 0.375 m without the chance constraint
  return RunScenario(sc, o, dir);
}

TEST(FormationFlightTest, FollowersSwappingSidesKeepTheCollisionRadius) {
  // Given the two followers of the triangle started on the wrong sides (they swap through
  // each other at the attitude bound right after the NMPC switch, both neighbour filters
  // lagging their 3.6 m/s^2), noise seed 3
  // When the collision constraint keeps r_min with 95 % under each estimate's uncertainty
  const nlohmann::json s = FlySwap(0.95);
  // Then they never come closer than r_min - 0.05 m, hold the formation afterwards and land
  const double r_min = 0.45;
  EXPECT_GE(s["min_separation_m"].get<double>(), r_min - 0.05) << s.dump(2);
  EXPECT_LE(s["steady_state_formation_error_m"].get<double>(), 0.05) << s.dump(2);
  EXPECT_EQ(s["fallbacks"].get<long>(), 0);
  EXPECT_TRUE(s["landed_safely"].get<bool>()) << s.dump(2);
  // while on the estimates alone (no margin, 0.5) the same seed came within 0.375 m
  const nlohmann::json plain = FlySwap(0.5);
  EXPECT_LT(plain["min_separation_m"].get<double>(), r_min - 0.05) << plain.dump(2);
  std::printf("[   INFO   ] swap, seed 3: min separation %.3f m (without the margin %.3f m)\n",
              s["min_separation_m"].get<double>(), plain["min_separation_m"].get<double>());
}

}  // namespace
}  // namespace fnmpc::experiment

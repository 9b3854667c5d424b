// SPDX-License-Identifier: BSD-3-Clause
// Cooperative mode: losing every message degrades to `wake` exactly (bit for bit,
// the whole closed loop: controllers, estimators, sensors, world with reality on), and with
// the link up the plans are delivered and change the flight.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {
namespace {

/// A vehicle log without its wall-clock column (solver_time: the only one that differs
/// between two runs of the same flight).
std::string Slurp(const std::string& path) {
  std::ifstream f(path);
  std::string line, out;
  std::vector<bool> skip;
  while (std::getline(f, line)) {
    std::stringstream cells(line);
    std::string cell;
    for (std::size_t c = 0; std::getline(cells, cell, ','); ++c) {
      if (skip.size() <= c) skip.push_back(cell == "solver_time");
      if (!skip[c]) out += cell + ",";
    }
    out += "\n";
  }
  return out;
}

TEST(CooperativeFlightTest, EveryMessageLostFliesExactlyAsWake) {
  // Given the shipped follower-below-leader scenario (reality on), its first 20 s (take-off,
  // the NMPC phase, the leader's first leg from 12 s),
  config::ScenarioConfig sc = config::LoadScenarioFile(
      std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/follower-below-leader.yaml");
  const std::string root =
      testing::TempDir() + "/fnmpc-integration-coop-" + std::to_string(getpid());
  std::filesystem::remove_all(root);
  RunOptions o;
  o.seed = sc.seed;
  o.duration = 20.0;
  auto fly = [&](formation::Compensation level, double loss, const std::string& name) {
    config::ScenarioConfig s = sc;
    s.compensation = level;
    s.link.loss_rate = loss;
    return RunScenario(s, o, root + "/" + name);
  };
  // When it is flown with `wake`, with `cooperative` losing every message, and with
  // `cooperative` on a link that loses none,
  const nlohmann::json wake = fly(formation::Compensation::kWake, 0.0, "wake");
  const nlohmann::json lost = fly(formation::Compensation::kCooperative, 1.0, "lost");
  const nlohmann::json up = fly(formation::Compensation::kCooperative, 0.0, "up");
  // then every vehicle's log of the all-lost run equals the wake run's byte for byte,
  for (const char* v : {"leader.csv", "follower.csv"}) {
    const std::string a = Slurp(root + "/wake/" + v);
    ASSERT_GT(a.size(), 1000U) << v;
    EXPECT_TRUE(a == Slurp(root + "/lost/" + v)) << v << " differs with every message lost";
  }
  // the link counted every plan as sent and lost,
  ASSERT_TRUE(lost.contains("link"));
  EXPECT_GT(lost["link"]["sent"].get<long>(), 100);
  EXPECT_EQ(lost["link"]["delivered"].get<long>(), 0);
  EXPECT_EQ(lost["link"]["lost"], lost["link"]["addressed"]);
  EXPECT_FALSE(wake.contains("link"));
  // The wake level's estimate of the leader's thrust from its motion stayed inside the
  // physically possible range at every step (formation::ThrustFromAcceleration's bounds).
  ASSERT_TRUE(wake["vehicles"]["follower"].contains("neighbour_thrust_bounded"));
  for (const char* reason : {"non_finite", "upside_down", "above_max"}) {
    EXPECT_EQ(wake["vehicles"]["follower"]["neighbour_thrust_bounded"][reason].get<long>(), 0)
        << reason;
  }
  // and with the link up the leader's plans reach the follower in time (the leader is the
  // follower's only neighbour and the follower nobody's: one receiver per plan)
  ASSERT_TRUE(up.contains("link"));
  // (all but the last, in flight when the run ends),
  EXPECT_GE(up["link"]["delivered"].get<long>(), up["link"]["addressed"].get<long>() - 1);
  EXPECT_EQ(up["link"]["lost"].get<long>(), 0);
  EXPECT_GT(up["link"]["delivered"].get<long>(), 100);
  EXPECT_EQ(up["link"]["late"].get<long>(), 0);
  // and change its flight.
  EXPECT_FALSE(Slurp(root + "/wake/follower.csv") == Slurp(root + "/up/follower.csv"));
  std::filesystem::remove_all(root);
}

}  // namespace
}  // namespace fnmpc::experiment

// SPDX-License-Identifier: BSD-3-Clause
// Faults of the scenario's `faults:` block in closed loop (shortened triangle, every sensor
// and estimator in the loop): a killed controller is landed by its autopilot's
// command-timeout failsafe, a vehicle with its motors off falls, forced solver failures drive
// the recovery ladder, dropout windows and outliers are counted.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {
namespace {

using json = nlohmann::json;

config::ScenarioConfig ShortTriangle() {
  config::ScenarioConfig sc =
      config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/triangle.yaml");
  sc.trajectory_start = 8.0;
  return Shortened(sc, 30.0);
}

config::VehicleFault Fault(const config::ScenarioConfig& sc, const std::string& name, double t) {
  config::VehicleFault f;
  f.vehicle = name;
  f.time = t;
  for (std::size_t i = 0; i < sc.vehicles.size(); ++i) {
    if (sc.vehicles[i].name == name) f.index = static_cast<int>(i);
  }
  return f;
}

std::string RunDir(const std::string& tag) {
  return testing::TempDir() + "/fnmpc-faults-" + tag + "-" + std::to_string(getpid());
}

json RunFaulty(const config::ScenarioConfig& sc, const std::string& tag) {
  const std::string dir = RunDir(tag);
  std::filesystem::remove_all(dir);
  RunOptions o;
  o.seed = 3;
  return RunScenario(sc, o, dir);
}

/// The true (x, y) [m] of the last row of a vehicle's CSV.
std::array<double, 2> LastPosition(const std::string& csv_path) {
  std::ifstream f(csv_path);
  std::string header, line, last;
  std::getline(f, header);
  while (std::getline(f, line)) {
    if (!line.empty()) last = line;
  }
  auto split = [](const std::string& l) {
    std::vector<std::string> out;
    std::stringstream ss(l);
    std::string cell;
    while (std::getline(ss, cell, ',')) out.push_back(cell);
    return out;
  };
  const auto names = split(header), values = split(last);
  std::array<double, 2> xy{kNaN, kNaN};
  for (std::size_t i = 0; i < names.size() && i < values.size(); ++i) {
    if (names[i] == "x") xy[0] = std::stod(values[i]);
    if (names[i] == "y") xy[1] = std::stod(values[i]);
  }
  return xy;
}

TEST(FaultFlightTest, KilledControllerIsLandedByItsAutopilot) {
  // Given the short triangle with follower2's controller killed in the hover at 12 s,
  config::ScenarioConfig sc = ShortTriangle();
  sc.faults.kill_controller = Fault(sc, "follower2", 12.0);
  // When it runs,
  const json s = RunFaulty(sc, "kill");
  ASSERT_TRUE(s.contains("faults")) << s.dump(2);
  const json& k = s["faults"]["kill_controller"];
  // Then the autopilot's failsafe engaged one timeout after the last command (sent at the
  // control step before the kill, Ts = 0.05 s earlier), at most one autopilot period late,
  ASSERT_TRUE(k["autopilot_failsafe"].get<bool>()) << k.dump(2);
  const double t_fs = k["autopilot_failsafe_time_s"].get<double>();
  EXPECT_GE(t_fs, 12.0 - 0.05 + 1.0 - 1e-6) << k.dump(2);
  EXPECT_LE(t_fs, 12.0 + 1.0 + 0.005) << k.dump(2);
  // it came down at about the failsafe's descent speed, the motors stopped, upright,
  ASSERT_TRUE(k["touchdown_vertical_speed_mps"].is_number()) << k.dump(2);
  EXPECT_GT(k["touchdown_vertical_speed_mps"].get<double>(), -0.9) << k.dump(2);
  EXPECT_TRUE(k["autopilot_disarm_time_s"].is_number()) << k.dump(2);
  // (the autopilot's 0.7 m/s is above the scenario's touchdown_speed_max of 0.6 m/s, so
  // landed_safely is not asked for here)
  EXPECT_LT(k["touchdown_vertical_speed_mps"].get<double>(), -0.5) << k.dump(2);
  EXPECT_TRUE(k["autopilot_landed"].get<bool>()) << k.dump(2);
  EXPECT_TRUE(s["vehicles"]["follower2"]["motors_off_at_end"].get<bool>());
  EXPECT_LT(s["vehicles"]["follower2"]["final_tilt_rad"].get<double>(), 0.05);
  // and the others still flew and landed.
  EXPECT_TRUE(s["faults"]["landed_safely_except_downed"].get<bool>()) << s.dump(2);
  EXPECT_EQ(s["faults"]["downed_vehicles"], json::array({"follower2"}));
  EXPECT_TRUE(k["followers"].contains("follower1")) << k.dump(2);
}

TEST(FaultFlightTest, VehicleWithMotorsOffFalls) {
  // Given the short triangle with follower1's motors off in the hover at 12 s (about 1 m up),
  config::ScenarioConfig sc = ShortTriangle();
  sc.faults.motors_off = Fault(sc, "follower1", 12.0);
  const json s = RunFaulty(sc, "motors");
  const json& f = s["faults"]["motors_off"];
  // Then it hits the ground about a free fall later, fast (not a landing),
  ASSERT_TRUE(f["impact_time_s"].is_number()) << f.dump(2);
  const double fall = f["impact_time_s"].get<double>() - 12.0;
  EXPECT_GT(fall, 0.25) << f.dump(2);  // sqrt(2 * 0.5 m / g) for a height above 0.6 m
  EXPECT_LT(fall, 0.8) << f.dump(2);   // sqrt(2 * 2 m / g) plus the 0.05 s sampling
  EXPECT_LT(f["impact_vertical_speed_mps"].get<double>(), -2.5) << f.dump(2);
  EXPECT_FALSE(s["vehicles"]["follower1"]["landed_safely"].get<bool>());
  // and the two others fly on and land safely.
  EXPECT_TRUE(s["faults"]["landed_safely_except_downed"].get<bool>()) << s.dump(2);
  EXPECT_TRUE(s["vehicles"]["leader"]["landed_safely"].get<bool>());
  EXPECT_TRUE(s["vehicles"]["follower2"]["landed_safely"].get<bool>());
}

TEST(FaultFlightTest, LeaderLandsClearOfAFallenFollowerBelowIt) {
  // Given the stacked scenario (follower `below` 0.5 m under the leader, wake on) shortened to
  // 30 s, with `below`'s motors off at 17 s while the leader holds its waypoint: it falls
  // onto the ground under the leader (fault campaign run 198 had a killed follower come to
  // rest 0.11 m beside the point under the leader, which then landed on it),
  config::ScenarioConfig sc = config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) +
                                                       "/config/scenarios/stress/stacked.yaml");
  sc = Shortened(sc, 30.0);
  sc.faults.motors_off = Fault(sc, "below", 17.0);
  const json s = RunFaulty(sc, "land-clear");
  ASSERT_TRUE(s["faults"]["motors_off"]["impact_time_s"].is_number());
  // (where it rests: it slides a little after the impact)
  const std::array<double, 2> fallen = LastPosition(RunDir("land-clear") + "/below.csv");
  const std::array<double, 2> leader = LastPosition(RunDir("land-clear") + "/leader.csv");
  const double r = sc.safety.collision_radius;
  // Then the leader, which senses it (relative sensor, a tracking slot for the vehicles
  // that are not its formation neighbours), moves its landing site clear (logged once) and
  // lands safely more than r_min from it, instead of onto it.
  const json& l = s["vehicles"]["leader"];
  EXPECT_EQ(l["landing_site_shifts"].get<long>(), 1) << l.dump(2);
  EXPECT_TRUE(l["landed_safely"].get<bool>()) << l.dump(2);
  const double d = std::hypot(leader[0] - fallen[0], leader[1] - fallen[1]);
  EXPECT_GT(d, r) << "leader at (" << leader[0] << ", " << leader[1] << "), fallen at ("
                  << fallen[0] << ", " << fallen[1] << ")";
  EXPECT_TRUE(s["vehicles"]["side"]["landed_safely"].get<bool>());
}

TEST(FaultFlightTest, FollowersLandWhenTheirLeaderIsDown) {
  // Given the short triangle (landing scheduled at 23 s) with the leader's controller killed
  // in the hover at 12 s: its autopilot lands it (fault campaign run 173: the leader's
  // failsafe landed it, and the two followers kept a formation with each other only, with
  // nothing to anchor it, drifting up to 2.3 m until their landing had not ended at 30 s),
  config::ScenarioConfig sc = ShortTriangle();
  sc.faults.kill_controller = Fault(sc, "leader", 12.0);
  const json s = RunFaulty(sc, "leader-down");
  ASSERT_TRUE(s["faults"]["kill_controller"]["touchdown_time_s"].is_number()) << s.dump(2);
  const double leader_down = s["faults"]["kill_controller"]["touchdown_time_s"].get<double>();
  // Then each follower, seeing its leader on the ground for neighbour_timeout, lands where it
  // is (logged with its reason, counted), long before the scheduled landing,
  EXPECT_EQ(s["leaderless_landings"].get<long>(), 2) << s.dump(2);
  for (const char* v : {"follower1", "follower2"}) {
    const json& j = s["vehicles"][v];
    EXPECT_EQ(j["leaderless_landing_reason"], "leader_down") << j.dump(2);
    ASSERT_TRUE(j["leaderless_landing_time_s"].is_number()) << j.dump(2);
    const double t_land = j["leaderless_landing_time_s"].get<double>();
    EXPECT_GE(t_land, leader_down) << j.dump(2);
    EXPECT_LT(t_land, leader_down + sc.safety.neighbour_timeout + 1.0) << j.dump(2);
    ASSERT_TRUE(j["touchdown_time_s"].is_number()) << j.dump(2);
    EXPECT_LT(j["touchdown_time_s"].get<double>(), config::LandingTime(sc, 1)) << j.dump(2);
    // safely, and no failsafe was needed.
    EXPECT_TRUE(j["landed_safely"].get<bool>()) << j.dump(2);
    EXPECT_EQ(j["failsafes"].get<long>(), 0) << j.dump(2);
  }
  EXPECT_TRUE(s["faults"]["landed_safely_except_downed"].get<bool>()) << s.dump(2);
}

TEST(FaultFlightTest, InjectedSolverFailuresReinitialiseAndMeasurementFaultsAreCounted) {
  // Given the short triangle with 30 % of the NMPC steps forced to fall back, a 1 s mocap
  // dropout window on the leader and 1 % outliers of size 0.2,
  config::ScenarioConfig sc = ShortTriangle();
  sc.faults.solver_failure_rate = 0.3;
  config::SensorDropoutWindow w;
  w.vehicle = "leader";
  w.index = sc.leader;
  w.sensor = SensorKind::kMocapPose;
  w.from = 15.0;
  w.to = 16.0;
  sc.faults.sensor_dropouts.push_back(w);
  sc.faults.outlier_rate = 0.01;
  sc.faults.outlier_size = 0.2;
  const json s = RunFaulty(sc, "solver");
  const json& f = s["faults"];
  // Then about 30 % of the steps were injected (binomial, 5 standard deviations),
  const double steps = f["solver_failures"]["nmpc_steps"].get<double>();
  const double injected = f["solver_failures"]["injected"].get<double>();
  ASSERT_GT(steps, 300.0) << f.dump(2);
  EXPECT_NEAR(injected / steps, 0.3, 5.0 * std::sqrt(0.3 * 0.7 / steps)) << f.dump(2);
  EXPECT_GE(s["fallbacks"].get<double>(), injected);
  // three in a row happened and the ladder re-initialised the solver,
  EXPECT_GT(s["recoveries"].get<long>(), 0) << s.dump(2);
  // the leader's 60 Hz mocap lost the samples stamped in [15, 16] s (61 of them),
  EXPECT_EQ(f["sensor_dropouts"][0]["dropped"].get<long>(), 61) << f.dump(2);
  // about 1 % of all measurements got an outlier,
  const double n = f["outliers"]["measurements"].get<double>();
  EXPECT_NEAR(f["outliers"]["corrupted"].get<double>() / n, 0.01, 5.0 * std::sqrt(0.01 / n));
  // and nothing produced a non-finite command: every vehicle is on the ground at the end.
  EXPECT_EQ(s["guarded_commands"].get<long>(), 0);
  for (const char* v : {"leader", "follower1", "follower2"}) {
    EXPECT_TRUE(s["vehicles"][v]["motors_off_at_end"].get<bool>()) << v;
  }
}

TEST(FaultFlightTest, EveryStepFailingHandsEveryVehicleToTheFailsafe) {
  // Given every NMPC step forced to fall back,
  config::ScenarioConfig sc = ShortTriangle();
  sc.faults.solver_failure_rate = 1.0;
  const json s = RunFaulty(sc, "solver-all");
  // Then the ladder re-initialises max_reinitialisations times per vehicle, gives up to the
  // failsafe, which lands every vehicle.
  for (const char* v : {"leader", "follower1", "follower2"}) {
    const json& j = s["vehicles"][v];
    EXPECT_EQ(j["recoveries"].get<long>(), sc.safety.recovery.max_reinitialisations) << v;
    EXPECT_EQ(j["failsafes"].get<long>(), 1) << v;
    EXPECT_EQ(j["failsafe_reason"], "reinitialisation_failed") << j.dump(2);
    EXPECT_TRUE(j["motors_off_at_end"].get<bool>()) << j.dump(2);
    // and each handover is a failure of the run (`fnmpc run` exits 3), naming the vehicle
    // and the reason (docs/failure.md "Exit codes": a failsafe must not leave the run a success).
    bool reported = false;
    for (const auto& f : s["failures"]) {
      reported = reported || (f["vehicle"] == v && f["reason"].get<std::string>().find(
                                                       "failsafe at t =") != std::string::npos);
    }
    EXPECT_TRUE(reported) << v << ": " << s["failures"].dump(2);
  }
}

}  // namespace
}  // namespace fnmpc::experiment

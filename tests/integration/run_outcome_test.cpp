// SPDX-License-Identifier: BSD-3-Clause
// A run's summary tells the truth (docs/failure.md): a vehicle outside any envelope, vehicles
// still in the air at the end and a vehicle that never took off are failures of the run, and a
// stopped run is marked incomplete.
#include <gtest/gtest.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {
namespace {

using json = nlohmann::json;

config::ScenarioConfig Triangle() {
  return config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) +
                                  "/config/scenarios/triangle.yaml");
}

std::string Dir(const std::string& tag) {
  const std::string dir =
      testing::TempDir() + "/fnmpc-outcome-" + tag + "-" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  return dir;
}

/// Every failure reason recorded for `vehicle`, one per line.
std::string Reasons(const json& s, const std::string& vehicle) {
  std::string out;
  for (const auto& f : s["failures"]) {
    if (f["vehicle"] == vehicle) out += f["reason"].get<std::string>() + "\n";
  }
  return out;
}

TEST(RunOutcomeTest, LeavingTheEnvelopeAndAnEarlyLandingAreReported) {
  // Given the triangle shortened to 18 s (landing at 9 s: its 9 s landing allowance kept)
  // with the leader landing 0.5 s into the formation
  // window and an envelope lower than the take-off height,
  config::ScenarioConfig sc = Triangle();
  sc.trajectory_start = 8.0;
  sc = Shortened(sc, 18.0);
  sc.vehicles[0].landing_time = 8.5;
  sc.envelope.max_altitude = 0.5;
  RunOptions o;
  o.seed = 3;
  // When it runs,
  const json s = RunScenario(sc, o, Dir("envelope"));
  // Then every vehicle is reported outside the envelope, with the time and the limit,
  ASSERT_TRUE(s["complete"].get<bool>()) << s.dump(2);
  for (const std::string name : {"leader", "follower1", "follower2"}) {
    const std::string r = Reasons(s, name);
    EXPECT_NE(r.find("left the flight envelope"), std::string::npos) << name << ": " << r;
    EXPECT_NE(r.find("max_altitude 0.50"), std::string::npos) << name << ": " << r;
  }
  // and each follower's formation window ends at its own landing (9 s), not the leader's
  // (8.5 s), with its whole-flight error reported beside it.
  const json& f1 = s["vehicles"]["follower1"];
  EXPECT_DOUBLE_EQ(f1["formation_window_s"][1].get<double>(), 9.0);
  ASSERT_TRUE(f1["formation_error_flight_max_m"].is_number()) << f1.dump(2);
  EXPECT_GE(f1["formation_error_flight_max_m"].get<double>(),
            f1["formation_error_max_m"].get<double>());
  EXPECT_GE(s["max_formation_error_flight_m"].get<double>(),
            f1["formation_error_flight_max_m"].get<double>());
}

TEST(RunOutcomeTest, VehiclesStillFlyingAtTheEndOrNeverAirborneFail) {
  // Given the triangle cut at 6 s (everyone hovering) and, second, with a thrust bound that
  // cannot lift a vehicle (bypassing the parser, which rejects it),
  config::ScenarioConfig sc = Triangle();
  RunOptions o;
  o.seed = 3;
  o.duration = 6.0;
  const json flying = RunScenario(sc, o, Dir("flying"));
  for (const std::string name : {"leader", "follower1", "follower2"}) {
    EXPECT_NE(Reasons(flying, name).find("not landed safely at the end"), std::string::npos)
        << flying["failures"].dump(2);
  }
  sc.thrust_min = 0.0;  // [0, 1] N: too little thrust to take off
  sc.thrust_max = 1.0;
  const json grounded = RunScenario(sc, o, Dir("grounded"));
  // Then the failures say so: airborne at the end, never took off.
  for (const std::string name : {"leader", "follower1", "follower2"}) {
    EXPECT_NE(Reasons(grounded, name).find("never took off"), std::string::npos)
        << grounded["failures"].dump(2);
  }
}

TEST(RunOutcomeTest, StoppedRunIsMarkedIncompleteAndKeepsItsLogs) {
  // Given a stop request (what SIGINT sets) before the first step,
  const config::ScenarioConfig sc = Triangle();
  volatile std::sig_atomic_t stop = SIGINT;
  RunOptions o;
  o.stop = &stop;
  const std::string dir = Dir("stopped");
  // When the run starts, it stops at once and writes what it has:
  const json s = RunScenario(sc, o, dir);
  EXPECT_FALSE(s["complete"].get<bool>());
  EXPECT_EQ(s["stopped"], "interrupted");
  // the summary on disk says so, and each vehicle's CSV holds its header.
  std::ifstream in(dir + "/summary.json");
  const json disk = json::parse(in);
  EXPECT_FALSE(disk["complete"].get<bool>());
  for (const std::string name : {"leader", "follower1", "follower2"}) {
    EXPECT_TRUE(std::filesystem::exists(dir + "/" + name + ".csv")) << name;
    EXPECT_FALSE(std::filesystem::exists(dir + "/" + name + ".csv.part")) << name;
  }
}

/// The failures of `kind` in a run summary.
std::vector<json> FailuresOf(const json& s, const std::string& kind) {
  std::vector<json> out;
  for (const auto& f : s["failures"]) {
    if (f.value("kind", "") == kind) out.push_back(f);
  }
  return out;
}

TEST(RunOutcomeTest, AVehicleFallingOntoAnotherIsACollision) {
  // Given the follower 0.8 m below its leader, the leader's motors stopped at 20 s (it falls
  // onto the follower: physics, not the controller, decides this one),
  config::ScenarioConfig sc =
      Shortened(config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) +
                                         "/config/scenarios/follower-below-leader.yaml"),
                30.0);
  sc.faults.motors_off.vehicle = "leader";
  sc.faults.motors_off.index = 0;
  sc.faults.motors_off.time = 20.0;
  RunOptions o;
  o.seed = 1;
  const json s = RunScenario(sc, o, Dir("collision"));
  // the run records the pair's closest approach below metrics.collision_distance (0.3 m),
  // and the collision is a failure naming both vehicles and its time.
  ASSERT_TRUE(s["complete"].get<bool>()) << s.dump(2);
  EXPECT_LT(s["min_separation_m"].get<double>(), 0.3);
  EXPECT_EQ(s["min_separation_pair"], json({"leader", "follower"}));
  EXPECT_GE(s["min_separation_time_s"].get<double>(), 20.0);
  EXPECT_EQ(s["collisions"].get<long>(), 1);
  const std::vector<json> c = FailuresOf(s, "collision");
  ASSERT_EQ(c.size(), 1u) << s["failures"].dump(2);
  EXPECT_EQ(c[0]["vehicles"], json({"leader", "follower"}));
  EXPECT_GE(c[0]["time_s"].get<double>(), 20.0);
  EXPECT_NE(c[0]["reason"].get<std::string>().find("collision with follower"), std::string::npos);
  EXPECT_EQ(s["vehicles"]["follower"]["min_separation_to"], "leader");
  EXPECT_LT(s["vehicles"]["follower"]["min_separation_m"].get<double>(), 0.3);
}

TEST(RunOutcomeTest, AFollowerDrivenIntoTheGroundStruckItAndDidNotLandSafely) {
  // Given the triangle with follower1's place 1.3 m below the leader's 1 m (under the ground)
  // and the soft minimum height off,
  config::ScenarioConfig sc = Shortened(Triangle(), 30.0);
  sc.vehicles[1].neighbours[0].desired.z() = 1.3;
  sc.vehicles[1].neighbours[1].desired.z() = 1.3;
  sc.vehicles[2].neighbours[1].desired.z() = -1.3;
  sc.safety.min_altitude = 0.0;
  RunOptions o;
  o.seed = 1;
  const json s = RunScenario(sc, o, Dir("strike"));
  // follower1 reaches the ground in its NMPC phase: a ground strike with its time, phase and
  // speed, it has not landed safely (whatever its touchdown later), and the others are clean.
  ASSERT_TRUE(s["complete"].get<bool>()) << s.dump(2);
  const json& f1 = s["vehicles"]["follower1"];
  ASSERT_TRUE(f1["ground_strike_time_s"].is_number()) << f1.dump(2);
  EXPECT_EQ(f1["ground_strike_phase"], "nmpc");
  EXPECT_LT(f1["ground_strike_vertical_speed_mps"].get<double>(), 0.0);
  EXPECT_FALSE(f1["landed_safely"].get<bool>());
  EXPECT_FALSE(s["landed_safely"].get<bool>());
  const std::vector<json> g = FailuresOf(s, "ground_strike");
  ASSERT_EQ(g.size(), 1u) << s["failures"].dump(2);
  EXPECT_EQ(g[0]["vehicle"], "follower1");
  EXPECT_DOUBLE_EQ(g[0]["time_s"].get<double>(), f1["ground_strike_time_s"].get<double>());
  EXPECT_EQ(s["ground_strikes"].get<long>(), 1);
  EXPECT_TRUE(s["vehicles"]["leader"]["ground_strike_time_s"].is_null());
  EXPECT_TRUE(s["vehicles"]["follower2"]["ground_strike_time_s"].is_null());
  EXPECT_EQ(s["collisions"].get<long>(), 0);
}

TEST(ShortenedTest, KeepsTheLandingAllowanceAndMovesEveryLandingTime) {
  const std::string dir = std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/";
  // Given every shipped scenario, its own duration changes nothing: the landing times, the
  // leader's waypoints and moves are the scenario's own.
  for (const char* name :
       {"triangle", "flying-leader-paper", "follower-below-leader", "manual-leader",
        "stress/stacked", "stress/leader-lands-early", "stress/wedge10-fast", "scale/wedge28"}) {
    const config::ScenarioConfig sc = config::LoadScenarioFile(dir + name + ".yaml");
    const config::ScenarioConfig same = Shortened(sc, sc.duration);
    EXPECT_EQ(same.landing_time, sc.landing_time) << name;
    EXPECT_EQ(same.waypoints.size(), sc.waypoints.size()) << name;
    EXPECT_EQ(same.walk_moves, sc.walk_moves) << name;
    for (std::size_t i = 0; i < sc.vehicles.size(); ++i) {
      EXPECT_EQ(config::LandingTime(same, static_cast<int>(i)),
                config::LandingTime(sc, static_cast<int>(i)))
          << name << " vehicle " << i;
    }
  }
  // Given the follower below its leader (82 s; the follower lands at 60 s, the leader at 73 s),
  // shortened to 30 s: the landing keeps its 9 s allowance (21 s), the follower's landing keeps
  // its place in the leader's flight (12 + 48 * 9 / 61 s), before the leader's, and the leader
  // keeps the one leg it finishes by then.
  const config::ScenarioConfig below = config::LoadScenarioFile(dir + "follower-below-leader.yaml");
  const config::ScenarioConfig s30 = Shortened(below, 30.0);
  EXPECT_DOUBLE_EQ(s30.duration, 30.0);
  EXPECT_DOUBLE_EQ(s30.landing_time, 21.0);
  EXPECT_DOUBLE_EQ(config::LandingTime(s30, 1), 12.0 + 48.0 * 9.0 / 61.0);
  EXPECT_DOUBLE_EQ(config::LandingTime(s30, 0), 21.0);
  EXPECT_EQ(s30.waypoints.size(), 1u);
  // The flying leader (74 s, landing at 64 s) at 40 s lands at 30 s after two legs.
  const config::ScenarioConfig fl40 =
      Shortened(config::LoadScenarioFile(dir + "flying-leader-paper.yaml"), 40.0);
  EXPECT_DOUBLE_EQ(fl40.landing_time, 30.0);
  EXPECT_EQ(fl40.waypoints.size(), 2u);
  // A duration that leaves no flight before the allowance is refused naming the flag and the
  // shortest duration.
  try {
    Shortened(below, 21.0);
    ADD_FAILURE() << "--duration 21 accepted";
  } catch (const config::ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("--duration 21"), std::string::npos) << what;
    EXPECT_NE(what.find("more than 21 s"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace fnmpc::experiment

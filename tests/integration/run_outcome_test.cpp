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

#include "apps/fnmpc/scenario_runner.hpp"
#include "fnmpc/config/scenario_yaml.hpp"

namespace fnmpc::app {
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
  // Given the triangle shortened to 16 s with the leader landing 0.5 s into the formation
  // window and an envelope lower than the take-off height,
  config::ScenarioConfig sc = Triangle();
  sc.trajectory_start = 8.0;
  sc = Shortened(sc, 16.0);
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

}  // namespace
}  // namespace fnmpc::app

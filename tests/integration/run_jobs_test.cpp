// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc run --runs N --jobs J` flies runs in parallel threads and writes
// the same run folder as --jobs 1 (each run depends only on its seed), wall-clock solver
// timings aside.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/run_folder.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

// Wall-clock measurements differ between any two runs; everything else must not.
bool IsTiming(const std::string& key) {
  return key.rfind("solver_time", 0) == 0 || key == "solver_steps_over_budget_share";
}

void DropTimings(json* j) {
  if (j->is_object()) {
    for (auto it = j->begin(); it != j->end();) {
      if (IsTiming(it.key())) {
        it = j->erase(it);
      } else {
        DropTimings(&it.value());
        ++it;
      }
    }
  } else if (j->is_array()) {
    for (json& e : *j) DropTimings(&e);
  }
}

json Summary(const std::string& path) {
  std::ifstream f(path);
  json j = json::parse(f);
  DropTimings(&j);
  return j;
}

// A CSV without its timing columns, as text.
std::string CsvWithoutTimings(const std::string& path) {
  std::ifstream f(path);
  std::string line, out;
  std::vector<bool> keep;
  while (std::getline(f, line)) {
    std::stringstream cells(line);
    std::string cell;
    std::size_t c = 0;
    const bool header = keep.empty();
    while (std::getline(cells, cell, ',')) {
      if (header) keep.push_back(!IsTiming(cell));
      if (c < keep.size() && keep[c]) out += cell + ",";
      ++c;
    }
    out += "\n";
  }
  return out;
}

TEST(RunJobsTest, ParallelRunsWriteTheSameFolderAsOneJob) {
  // Given the triangle shortened to 25 s (take-off, one leg, landing), three runs,
  config::ScenarioConfig sc =
      config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/triangle.yaml");
  sc = Shortened(sc, 25.0);
  const std::string base = testing::TempDir() + "/fnmpc-jobs-" + std::to_string(getpid());
  fs::remove_all(base);
  RunFolderOptions o;
  o.runs = 3;
  o.seed = 5;
  // when flown with one job and with three,
  o.jobs = 1;
  const json one = RunFolder(sc, o, base + "/one");
  o.jobs = 3;
  const json three = RunFolder(sc, o, base + "/three");
  // then both summaries and every CSV agree, timings aside.
  ASSERT_EQ(one["runs"].get<int>(), 3);
  EXPECT_EQ(Summary(base + "/one/summary.json"), Summary(base + "/three/summary.json"));
  int csvs = 0;
  for (const auto& e : fs::recursive_directory_iterator(base + "/one")) {
    if (e.path().extension() != ".csv") continue;
    const std::string rel = fs::relative(e.path(), base + "/one").string();
    ASSERT_TRUE(fs::exists(base + "/three/" + rel)) << rel;
    EXPECT_EQ(CsvWithoutTimings(e.path().string()), CsvWithoutTimings(base + "/three/" + rel))
        << rel;
    ++csvs;
  }
  EXPECT_EQ(csvs, 9);  // 3 runs x 3 vehicles
  o.jobs = 0;
  EXPECT_THROW(RunFolder(sc, o, base + "/zero"), std::invalid_argument);
  fs::remove_all(base);
}

// Every CSV of folder `a` equals the one of the same name in `b`, timings aside; returns how
// many were compared.
int CompareCsvs(const std::string& a, const std::string& b) {
  int csvs = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    if (e.path().extension() != ".csv") continue;
    const std::string rel = fs::relative(e.path(), a).string();
    EXPECT_TRUE(fs::exists(b + "/" + rel)) << rel;
    EXPECT_EQ(CsvWithoutTimings(e.path().string()), CsvWithoutTimings(b + "/" + rel)) << rel;
    ++csvs;
  }
  return csvs;
}

// Flies one run of `sc` with one thread and with `threads`, expects the same summaries and
// CSVs (timings aside) and returns the run's summary.
json RunSummaryIfThreadsAgree(const config::ScenarioConfig& sc, int seed, int threads,
                              const std::string& name) {
  const std::string base = testing::TempDir() + "/fnmpc-" + name + "-" + std::to_string(getpid());
  fs::remove_all(base);
  RunFolderOptions o;
  o.seed = seed;
  o.threads = 1;
  RunFolder(sc, o, base + "/one");
  o.threads = threads;
  RunFolder(sc, o, base + "/many");
  EXPECT_EQ(Summary(base + "/one/summary.json"), Summary(base + "/many/summary.json"));
  EXPECT_EQ(CompareCsvs(base + "/one", base + "/many"), static_cast<int>(sc.vehicles.size()));
  const json run = Summary(base + "/one/run-01/summary.json");
  fs::remove_all(base);
  return run;
}

TEST(RunJobsTest, ThreadsPerRunWriteTheSameFolderAsOne) {
  // Given the 10-vehicle wedge shortened to 25 s with 4 tracking slots per controller (the
  // slots change hands) and one follower's controller killed at 18 s,
  config::ScenarioConfig sc = config::LoadScenarioFile(
      std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/stress/wedge10-fast.yaml");
  sc = Shortened(sc, 25.0);
  sc.max_tracked = 4;
  sc.faults.kill_controller.vehicle = sc.vehicles[4].name;
  sc.faults.kill_controller.index = 4;
  sc.faults.kill_controller.time = 18.0;
  // when flown with one thread and with three, then the summaries and every CSV agree,
  // timings aside,
  const json run = RunSummaryIfThreadsAgree(sc, 3, 3, "threads");
  // and the run did fly (the killed controller's vehicle was landed by its autopilot).
  EXPECT_TRUE(run.contains("faults")) << run.dump();
  EXPECT_GT(run["vehicles"][sc.vehicles[9].name]["depth"].get<int>(), 1);
  EXPECT_EQ(run["vehicles"][sc.vehicles[sc.leader].name]["depth"].get<int>(), 0);
  RunFolderOptions o;
  o.threads = 0;
  EXPECT_THROW(RunFolder(sc, o, testing::TempDir() + "/fnmpc-zero"), std::invalid_argument);
}

TEST(RunJobsTest, ThreadsPerRunWriteTheSameFolderAsOneWithPlansAndSensorFaults) {
  // Given the triangle shortened to 25 s in cooperative mode (plans over the link, delivered
  // at the control steps while a thread of its own feeds the measurements), with outliers
  // and a window without motion capture for one follower,
  config::ScenarioConfig sc =
      config::LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/triangle.yaml");
  sc = Shortened(sc, 25.0);
  sc.compensation = formation::Compensation::kCooperative;
  sc.faults.outlier_rate = 0.01;
  sc.faults.outlier_size = 0.5;
  config::SensorDropoutWindow window;
  window.vehicle = sc.vehicles[1].name;
  window.index = 1;
  window.sensor = SensorKind::kMocapPose;
  window.from = 12.0;
  window.to = 13.5;
  sc.faults.sensor_dropouts.push_back(window);
  // when flown with one thread and with two, then the summaries and every CSV agree,
  // timings aside,
  const json run = RunSummaryIfThreadsAgree(sc, 7, 2, "threads-coop");
  // and the plans and the faults were there to be ordered.
  EXPECT_GT(run["link"]["delivered"].get<int>(), 0) << run.dump();
  EXPECT_GT(run["faults"]["outliers"]["corrupted"].get<int>(), 0) << run.dump();
}

}  // namespace
}  // namespace fnmpc::experiment

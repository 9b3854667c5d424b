// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc run SCENARIO.yaml`: runs a formation scenario in the simulator (all sensors and
// estimators in the loop) and writes a run folder with CSV logs and summary.json.
#include <fmt/chrono.h>
#include <fmt/core.h>

#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <memory>

#include "apps/fnmpc/commands.hpp"
#include "apps/fnmpc/scenario_runner.hpp"
#include "fnmpc/config/scenario_yaml.hpp"

namespace fnmpc::app {
namespace {

struct RunArgs {
  std::string scenario;
  std::string out;
  int runs = 1;
  int seed = -1;
  double duration = -1.0;
  bool quiet = false;
  std::string downwash;  // "", "on", "off"
};

int Run(const RunArgs& a) {
  config::ScenarioConfig sc = config::LoadScenarioFile(a.scenario);
  if (a.duration > 0.0) sc = Shortened(sc, a.duration);
  if (!a.downwash.empty()) sc.downwash = a.downwash == "on";
  std::string dir = a.out;
  if (dir.empty()) {
    const std::time_t now = std::time(nullptr);
    dir = fmt::format("runs/{}-{:%Y%m%d-%H%M%S}", sc.name, fmt::localtime(now));
  }
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(a.scenario, dir + "/scenario.yaml",
                             std::filesystem::copy_options::overwrite_existing);
  const std::uint64_t seed0 = a.seed >= 0 ? static_cast<std::uint64_t>(a.seed) : sc.seed;
  std::vector<nlohmann::json> runs;
  for (int r = 0; r < a.runs; ++r) {
    RunOptions o;
    o.seed = seed0 + static_cast<std::uint64_t>(r);
    o.progress = !a.quiet;
    o.label = fmt::format("[{} run {}/{} seed {}]", sc.name, r + 1, a.runs, o.seed);
    const std::string rdir = fmt::format("{}/run-{:02d}", dir, r + 1);
    nlohmann::json s = RunScenario(sc, o, rdir);
    s["dir"] = fmt::format("run-{:02d}", r + 1);
    runs.push_back(s);
    if (!a.quiet) {
      fmt::print(
          stderr,
          "  steady-state formation error {:.4f} m, max {:.3f} m, solver max {:.2f} ms, "
          "fallbacks {}, landed safely {}\n",
          s["steady_state_formation_error_m"].is_number()
              ? s["steady_state_formation_error_m"].get<double>()
              : -1.0,
          s["max_formation_error_m"].is_number() ? s["max_formation_error_m"].get<double>() : -1.0,
          s["solver_time_max_s"].is_number() ? 1e3 * s["solver_time_max_s"].get<double>() : -1.0,
          s["fallbacks"].get<long>(), s["landed_safely"].get<bool>());
    }
  }
  nlohmann::json summary = AggregateRuns(runs);
  summary["scenario_file"] = a.scenario;
  std::ofstream(dir + "/summary.json") << summary.dump(2) << "\n";
  fmt::print("{}\n", dir);
  return 0;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* sub = app.add_subcommand("run", "Run a formation scenario in the simulator");
  sub->add_option("scenario", a->scenario,
                  "scenario YAML (config/scenarios/*.yaml, docs/scenarios.md)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("-o,--out", a->out, "run folder (default runs/<scenario>-<timestamp>)");
  sub->add_option("--runs", a->runs, "number of runs with seeds seed, seed+1, ...")
      ->check(CLI::PositiveNumber);
  sub->add_option("--seed", a->seed, "first noise seed (default: the scenario's)");
  sub->add_option("--duration", a->duration,
                  "shorten the scenario to this simulated time [s] (fewer legs, earlier landing)");
  sub->add_option("--downwash", a->downwash, "override the scenario's downwash switch")
      ->check(CLI::IsMember({"on", "off"}));
  sub->add_flag("-q,--quiet", a->quiet, "no progress output");
  registry.push_back({sub, [a] { return Run(*a); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

// SPDX-License-Identifier: BSD-3-Clause
#include "apps/fnmpc/run_folder.hpp"

#include <fmt/core.h>

#include <filesystem>
#include <stdexcept>
#include <vector>

#include "apps/fnmpc/output_files.hpp"
#include "apps/fnmpc/scenario_runner.hpp"

namespace fnmpc::app {

namespace {
double NumberOr(const nlohmann::json& j, const char* key, double fallback) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : fallback;
}
bool Stopped(const RunFolderOptions& o) { return o.stop != nullptr && *o.stop != 0; }
}  // namespace

nlohmann::json RunFolder(const config::ScenarioConfig& sc, const RunFolderOptions& options,
                         const std::string& dir) {
  if (options.runs < 1) {
    throw std::invalid_argument("RunFolder: runs must be >= 1, got " +
                                std::to_string(options.runs));
  }
  std::filesystem::create_directories(dir);
  if (!options.scenario_file.empty() && std::filesystem::is_regular_file(options.scenario_file)) {
    std::filesystem::copy_file(options.scenario_file, PathInside(dir, "scenario.yaml"),
                               std::filesystem::copy_options::overwrite_existing);
  }
  const std::uint64_t seed0 =
      options.seed >= 0 ? static_cast<std::uint64_t>(options.seed) : sc.seed;
  std::vector<nlohmann::json> runs;
  bool sim_failed = false;
  for (int r = 0; r < options.runs && !Stopped(options); ++r) {
    RunOptions o;
    o.seed = seed0 + static_cast<std::uint64_t>(r);
    o.progress = options.progress;
    o.label = fmt::format("[{} run {}/{} seed {}]", sc.name, r + 1, options.runs, o.seed);
    o.stop = options.stop;
    nlohmann::json s = RunScenario(sc, o, fmt::format("{}/run-{:02d}", dir, r + 1));
    s["dir"] = fmt::format("run-{:02d}", r + 1);
    if (s.contains("error")) {
      sim_failed = true;
      fmt::print(stderr, "fnmpc run: {}: simulation stopped: {}\n", s["dir"].get<std::string>(),
                 s["error"].get<std::string>());
    }
    runs.push_back(s);
    if (options.progress) {
      fmt::print(stderr,
                 "  steady-state formation error {:.4f} m, max {:.3f} m, solver max {:.2f} ms, "
                 "fallbacks {}, landed safely {}\n",
                 NumberOr(s, "steady_state_formation_error_m", -1.0),
                 NumberOr(s, "max_formation_error_m", -1.0),
                 1e3 * NumberOr(s, "solver_time_max_s", -1e-3), s["fallbacks"].get<long>(),
                 s["landed_safely"].get<bool>());
    }
    if (sim_failed) break;
  }
  nlohmann::json summary = runs.empty() ? nlohmann::json::object() : AggregateRuns(runs);
  summary["scenario_file"] = options.scenario_file;
  summary["runs_requested"] = options.runs;
  summary["reality"] = sc.reality.enabled;
  summary["complete"] = !Stopped(options) && !sim_failed &&
                        static_cast<int>(runs.size()) == options.runs &&
                        summary.value("complete", false);
  if (Stopped(options)) summary["stopped"] = "interrupted";
  WriteFileAtomically(PathInside(dir, "summary.json"),
                      summary.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  return summary;
}

}  // namespace fnmpc::app

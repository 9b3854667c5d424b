// SPDX-License-Identifier: BSD-3-Clause
#include "apps/fnmpc/run_folder.hpp"

#include <fmt/core.h>

#include <atomic>
#include <exception>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <thread>
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
  if (options.threads < 1) {
    throw std::invalid_argument("RunFolder: threads must be >= 1, got " +
                                std::to_string(options.threads));
  }
  if (options.jobs < 1) {
    throw std::invalid_argument("RunFolder: jobs must be >= 1, got " +
                                std::to_string(options.jobs));
  }
  const std::uint64_t seed0 =
      options.seed >= 0 ? static_cast<std::uint64_t>(options.seed) : sc.seed;
  // Run r writes only run-NN/ and results[r] (null until it is done); the workers take the next run
  // index. A run the simulator failed ends the folder after it, as with one job: later runs are not
  // started, and those already flown are removed below.
  std::vector<nlohmann::json> results(static_cast<std::size_t>(options.runs));
  std::atomic<int> next{0};
  std::atomic<int> first_failure{options.runs};
  std::mutex print_mutex;
  const auto fly = [&] {
    for (int r = next++; r < options.runs && r < first_failure && !Stopped(options); r = next++) {
      RunOptions o;
      o.seed = seed0 + static_cast<std::uint64_t>(r);
      o.progress = options.progress;
      o.label = fmt::format("[{} run {}/{} seed {}]", sc.name, r + 1, options.runs, o.seed);
      o.stop = options.stop;
      o.threads = options.threads;
      nlohmann::json s = RunScenario(sc, o, fmt::format("{}/run-{:02d}", dir, r + 1));
      s["dir"] = fmt::format("run-{:02d}", r + 1);
      const std::lock_guard<std::mutex> lock(print_mutex);
      if (s.contains("error")) {
        if (r < first_failure) first_failure = r;  // written under the lock only
        fmt::print(stderr, "fnmpc run: {}: simulation stopped: {}\n", s["dir"].get<std::string>(),
                   s["error"].get<std::string>());
      }
      if (options.progress) {
        fmt::print(stderr,
                   "  {}steady-state formation error {:.4f} m, max {:.3f} m, solver max {:.2f} "
                   "ms, fallbacks {}, landed safely {}\n",
                   options.jobs > 1 ? o.label + " " : std::string(),
                   NumberOr(s, "steady_state_formation_error_m", -1.0),
                   NumberOr(s, "max_formation_error_m", -1.0),
                   1e3 * NumberOr(s, "solver_time_max_s", -1e-3), s["fallbacks"].get<long>(),
                   s["landed_safely"].get<bool>());
      }
      results[static_cast<std::size_t>(r)] = std::move(s);
    }
  };
  std::exception_ptr error;  // the first exception of a worker, rethrown after the join
  const auto worker = [&] {
    try {
      fly();
    } catch (...) {
      const std::lock_guard<std::mutex> lock(print_mutex);
      if (!error) error = std::current_exception();
      next = options.runs;  // no new runs
    }
  };
  const int threads = std::min(options.jobs, options.runs);
  if (threads == 1) {
    worker();
  } else {
    std::vector<std::jthread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  }
  if (error) std::rethrow_exception(error);
  const bool sim_failed = first_failure < options.runs;
  // The runs of the folder: from the first on, each done, up to the failed one.
  std::vector<nlohmann::json> runs;
  for (int r = 0; r < options.runs; ++r) {
    const auto k = static_cast<std::size_t>(r);
    const bool done = !results[k].is_null();
    if (!done || r > first_failure) {
      // Flown after the failed run (or not at all): not part of the folder.
      std::error_code ec;
      if (done) std::filesystem::remove_all(fmt::format("{}/run-{:02d}", dir, r + 1), ec);
      continue;
    }
    runs.push_back(std::move(results[k]));
  }
  nlohmann::json summary = runs.empty() ? nlohmann::json::object() : AggregateRuns(runs);
  summary["scenario_file"] = options.scenario_file;
  summary["runs_requested"] = options.runs;
  summary["reality"] = sc.reality.enabled;
  summary["compensation"] = formation::ToString(sc.compensation);
  summary["complete"] = !Stopped(options) && !sim_failed &&
                        static_cast<int>(runs.size()) == options.runs &&
                        summary.value("complete", false);
  if (Stopped(options)) summary["stopped"] = "interrupted";
  WriteFileAtomically(PathInside(dir, "summary.json"),
                      summary.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  return summary;
}

}  // namespace fnmpc::app

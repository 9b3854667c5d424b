// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/run_folder.hpp"

#include <fmt/core.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <cmath>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "fnmpc/config/output_files.hpp"
#include "fnmpc/experiment/folder_manifest.hpp"
#include "fnmpc/experiment/run_folder_detail.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace run_folder_detail {

std::string RunDir(int r) { return fmt::format("run-{:02d}", r + 1); }

std::string ReadText(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": cannot read");
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}
json ReadJson(const std::string& path) {
  try {
    return json::parse(ReadText(path));
  } catch (const json::exception& e) {
    throw std::runtime_error(path + ": not a summary (" + e.what() + ")");
  }
}
void WriteSummary(const std::string& dir, const json& summary) {
  config::WriteFileAtomically(config::PathInside(dir, "summary.json"),
                              summary.dump(2, ' ', false, json::error_handler_t::replace) + "\n");
}

/// The folder's summary from its runs, in run order: the same for RunFolder and the merge.
json FolderSummary(const json& identity, std::vector<json> runs, int expected, bool stopped,
                   bool sim_failed) {
  const std::size_t count = runs.size();
  json summary = runs.empty() ? json::object() : AggregateRuns(runs);
  summary.update(identity);
  summary["complete"] = !stopped && !sim_failed && static_cast<int>(count) == expected &&
                        summary.value("complete", false);
  if (stopped) summary["stopped"] = "interrupted";
  return summary;
}

/// Why `--overwrite` refuses a folder without a manifest, and what to do.
std::string NoManifest(const std::string& dir) {
  return fmt::format(
      "{}: --overwrite deletes only files fnmpc wrote, and this folder has no {} listing "
      "them: it is not a folder of fnmpc (or one written by an earlier fnmpc, which "
      "kept no manifest); nothing deleted: delete it yourself or choose another -o",
      dir, kManifestName);
}

}  // namespace run_folder_detail

using namespace run_folder_detail;  // NOLINT: this file's own helpers

namespace {

double NumberOr(const json& j, const char* key, double fallback) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : fallback;
}
bool Stopped(const RunFolderOptions& o) { return o.stop != nullptr && *o.stop != 0; }

/// The files RunScenario writes into run r's folder (run_loop.cpp, scenario_runner.cpp):
/// a CSV per vehicle, the drawn plants with reality on, the run's summary. Listed in the
/// manifest before the run begins; tests/integration/run_shard_test.cpp checks that they
/// are all the run writes.
std::vector<std::string> RunFiles(const config::ScenarioConfig& sc, int r) {
  std::vector<std::string> files;
  for (const auto& v : sc.vehicles) {
    files.push_back(RunDir(r) + "/" + v.name + ".csv");
    if (sc.reality.enabled) files.push_back(RunDir(r) + "/plant-" + v.name + ".yaml");
  }
  files.push_back(RunDir(r) + "/summary.json");
  return files;
}

/// A run's summary from an earlier attempt when it finished, else null.
json FinishedRun(const std::string& dir, int r) {
  const std::string path = config::PathInside(config::PathInside(dir, RunDir(r)), "summary.json");
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return nullptr;
  json s = json::parse(ReadText(path), nullptr, false);
  if (s.is_discarded() || !s.value("complete", false) || s.contains("error")) return nullptr;
  s["dir"] = RunDir(r);
  return s;
}

}  // namespace

Shard ParseShard(const std::string& text) {
  Shard s;
  s.sharded = true;
  const auto slash = text.find('/');
  const auto number = [&](std::string_view part, int* v) {
    const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), *v);
    return ec == std::errc() && end == part.data() + part.size() && !part.empty();
  };
  const std::string_view all(text);
  if (slash == std::string::npos || !number(all.substr(0, slash), &s.index) ||
      !number(all.substr(slash + 1), &s.count) || s.count < 1 || s.count > 10000 || s.index < 0 ||
      s.index >= s.count) {
    throw std::invalid_argument("shard '" + text +
                                "': expected I/N with 0 <= I < N <= 10000 (e.g. 0/4)");
  }
  return s;
}

void PrepareRunFolder(const std::string& dir, bool overwrite) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    throw std::runtime_error(dir + ": exists and is not a folder");
  }
  if (fs::is_directory(dir, ec) && !fs::is_empty(dir, ec)) {
    if (!overwrite) {
      throw std::runtime_error(dir +
                               ": run folder is not empty (an earlier run?); use "
                               "--overwrite to delete the files fnmpc wrote there, --resume to "
                               "finish it, or choose another -o");
    }
    if (!FolderManifest::Exists(dir)) throw std::runtime_error(NoManifest(dir));
    // Only what fnmpc listed goes; a user's own files in the folder stay.
    DeleteListedFiles(dir, FolderManifest::Read(dir));
  }
  try {
    fs::create_directories(dir);
  } catch (const fs::filesystem_error& e) {
    throw std::runtime_error(dir + ": cannot create the folder: " + e.code().message());
  }
  FolderManifest().Write(dir);  // the folder is fnmpc's from now on
}

json FolderIdentity(const config::ScenarioConfig& sc, const RunFolderOptions& options) {
  json id;
  id["scenario"] = sc.name;
  id["scenario_file"] = options.scenario_file;
  id["runs_requested"] = options.runs;
  id["first_seed"] = options.seed >= 0 ? static_cast<std::uint64_t>(options.seed) : sc.seed;
  id["duration_s"] = sc.duration;
  id["reality"] = sc.reality.enabled;
  id["downwash"] = sc.downwash;
  id["compensation"] = formation::ToString(sc.compensation);
  id["timing"] = options.timing;
  return id;
}

void CheckResumable(const config::ScenarioConfig& sc, const RunFolderOptions& options,
                    const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec) || fs::is_empty(dir, ec)) return;
  const std::string path = config::PathInside(dir, "summary.json");
  if (!fs::is_regular_file(path, ec)) {
    throw std::runtime_error(dir +
                             ": not a run folder of `fnmpc run` (no summary.json); "
                             "--resume needs the folder of an earlier attempt");
  }
  if (!FolderManifest::Exists(dir)) {
    throw std::runtime_error(
        fmt::format("{}: no {}: written by an earlier fnmpc (or not by fnmpc); --resume continues "
                    "only folders with a manifest: delete it yourself and fly it again",
                    dir, kManifestName));
  }
  const json s = ReadJson(path);
  json id = FolderIdentity(sc, options);
  if (!options.shard.whole()) {
    id[kShardKey] = fmt::format("{}/{}", options.shard.index, options.shard.count);
  }
  for (const auto& [key, value] : id.items()) {
    if (!s.contains(key) || s[key] != value) {
      throw std::runtime_error(fmt::format(
          "{}: key '{}': {} in the folder, {} in this command: --resume continues only the "
          "same experiment",
          path, key, s.contains(key) ? s[key].dump() : std::string("missing"), value.dump()));
    }
  }
  if (!s.contains(kShardKey) && !options.shard.whole()) {
    throw std::runtime_error(path + ": key 'shard': missing in the folder");
  }
  if (!options.scenario_file.empty() &&
      ReadText(config::PathInside(dir, "scenario.yaml")) != ReadText(options.scenario_file)) {
    throw std::runtime_error(config::PathInside(dir, "scenario.yaml") + ": differs from " +
                             options.scenario_file + ": --resume continues only the same scenario");
  }
}

json RunFolder(const config::ScenarioConfig& sc, const RunFolderOptions& options,
               const std::string& dir) {
  if (options.runs < 1) {
    throw std::invalid_argument("RunFolder: runs must be >= 1, got " +
                                std::to_string(options.runs));
  }
  if (options.threads < 1) {
    throw std::invalid_argument("RunFolder: threads must be >= 1, got " +
                                std::to_string(options.threads));
  }
  if (options.jobs < 1) {
    throw std::invalid_argument("RunFolder: jobs must be >= 1, got " +
                                std::to_string(options.jobs));
  }
  const Shard shard = options.shard;
  if (shard.count < 1 || shard.index < 0 || shard.index >= shard.count) {
    throw std::invalid_argument(
        fmt::format("RunFolder: shard {}/{} is not one of the shards", shard.index, shard.count));
  }
  fs::create_directories(dir);
  // Every file written here is listed in the folder's manifest before it is begun and again,
  // with its size and digest, when it is done (kept from an earlier attempt with --resume; a
  // new folder starts an empty one and claims none of the files already there).
  FolderManifest manifest =
      FolderManifest::Exists(dir) ? FolderManifest::Read(dir) : FolderManifest();
  manifest.Write(dir);
  std::mutex manifest_mutex;
  const auto plan = [&](const std::vector<std::string>& files) {
    const std::lock_guard<std::mutex> lock(manifest_mutex);
    for (const std::string& f : files) manifest.Plan(f);
    manifest.Append(dir, files);
  };
  const auto record = [&](const std::vector<std::string>& files) {
    const std::lock_guard<std::mutex> lock(manifest_mutex);
    for (const std::string& f : files) {
      std::error_code ec;
      if (fs::is_regular_file(dir + "/" + f, ec)) {
        manifest.Record(dir, f);
      } else {
        manifest.Forget(f);
      }
    }
    manifest.Append(dir, files);
  };
  if (!options.scenario_file.empty() && fs::is_regular_file(options.scenario_file)) {
    std::error_code ec;
    if (!fs::equivalent(options.scenario_file, config::PathInside(dir, "scenario.yaml"), ec)) {
      plan({"scenario.yaml"});
      fs::copy_file(options.scenario_file, config::PathInside(dir, "scenario.yaml"),
                    fs::copy_options::overwrite_existing);
      record({"scenario.yaml"});
    }
  }
  json identity = FolderIdentity(sc, options);
  if (!shard.whole()) identity[kShardKey] = fmt::format("{}/{}", shard.index, shard.count);
  const std::uint64_t seed0 = identity["first_seed"].get<std::uint64_t>();
  // This folder's runs (all, or the shard's), in run order; those an earlier attempt finished
  // are kept. The summary names the experiment from the start, so that an attempt killed
  // before its end can be resumed.
  std::vector<int> mine;
  for (int r = 0; r < options.runs; ++r) {
    if (shard.Has(r)) mine.push_back(r);
  }
  const int n = static_cast<int>(mine.size());
  std::vector<json> results(static_cast<std::size_t>(n));
  int kept = 0;
  if (options.resume) {
    for (int k = 0; k < n; ++k) {
      results[static_cast<std::size_t>(k)] = FinishedRun(dir, mine[static_cast<std::size_t>(k)]);
      kept += results[static_cast<std::size_t>(k)].is_null() ? 0 : 1;
    }
    if (options.progress && kept > 0) {
      fmt::print(stderr, "fnmpc run: resuming {}: {} of {} runs already complete\n", dir, kept, n);
    }
  }
  plan({"summary.json"});
  WriteSummary(dir, FolderSummary(identity, {}, n, true, false));
  record({"summary.json"});
  if (options.resume) {
    // A kept run's files an attempt killed before recording them: recorded as they are (the
    // run's summary says it is complete).
    for (int k = 0; k < n; ++k) {
      if (results[static_cast<std::size_t>(k)].is_null()) continue;
      std::vector<std::string> unrecorded;
      for (const std::string& f : RunFiles(sc, mine[static_cast<std::size_t>(k)])) {
        const auto it = manifest.entries().find(f);
        if (it == manifest.entries().end() || !it->second.finished()) unrecorded.push_back(f);
      }
      record(unrecorded);
    }
  }
  // Run k writes only its run-NN/ and results[k] (null until it is done); the workers take the
  // next index. A run the simulator failed ends the folder after it, as with one job: later
  // runs are not started, and those already flown are removed below.
  std::atomic<int> next{0};
  std::atomic<int> first_failure{n};
  std::mutex print_mutex;
  const auto fly = [&] {
    for (int k = next++; k < n && k < first_failure && !Stopped(options); k = next++) {
      if (!results[static_cast<std::size_t>(k)].is_null()) continue;
      const int r = mine[static_cast<std::size_t>(k)];
      RunOptions o;
      o.seed = seed0 + static_cast<std::uint64_t>(r);
      o.progress = options.progress;
      o.label = fmt::format("[{} run {}/{} seed {}]", sc.name, r + 1, options.runs, o.seed);
      o.stop = options.stop;
      o.threads = options.threads;
      o.timing = options.timing;
      const std::vector<std::string> files = RunFiles(sc, r);
      plan(files);
      json s = RunScenario(sc, o, config::PathInside(dir, RunDir(r)));
      record(files);
      s["dir"] = RunDir(r);
      const std::lock_guard<std::mutex> lock(print_mutex);
      if (s.contains("error")) {
        if (k < first_failure) first_failure = k;  // written under the lock only
        fmt::print(stderr, "fnmpc run: {}: simulation stopped (seed {}): {}\n",
                   s["dir"].get<std::string>(), o.seed, s["error"].get<std::string>());
      }
      if (options.progress) {
        const double solver_max = NumberOr(s, "solver_time_max_s", kNaN);
        fmt::print(stderr,
                   "  {}steady-state formation error {:.4f} m, max {:.3f} m, solver max {}, "
                   "fallbacks {}, landed safely {}\n",
                   options.jobs > 1 ? o.label + " " : std::string(),
                   NumberOr(s, "steady_state_formation_error_m", -1.0),
                   NumberOr(s, "max_formation_error_m", -1.0),
                   std::isfinite(solver_max) ? fmt::format("{:.2f} ms", 1e3 * solver_max)
                                             : std::string("not timed"),
                   s["fallbacks"].get<long>(), s["landed_safely"].get<bool>());
      }
      results[static_cast<std::size_t>(k)] = std::move(s);
    }
  };
  std::exception_ptr error;  // the first exception of a worker, rethrown after the join
  const auto worker = [&] {
    try {
      fly();
    } catch (...) {
      const std::lock_guard<std::mutex> lock(print_mutex);
      if (!error) error = std::current_exception();
      next = n;  // no new runs
    }
  };
  const int threads = std::min(options.jobs, std::max(1, n - kept));
  if (threads == 1) {
    worker();
  } else {
    std::vector<std::jthread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  }
  if (error) std::rethrow_exception(error);
  const bool sim_failed = first_failure < n;
  // The runs of the folder: from the first on, each done, up to the failed one.
  std::vector<json> runs;
  for (int k = 0; k < n; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const bool done = !results[i].is_null();
    if (!done || k > first_failure) {
      // Flown after the failed run (or not at all): not part of the folder.
      if (done) {
        DeleteListedFiles(dir, manifest, RunDir(mine[i]));
        manifest.Forget(RunDir(mine[i]));
      }
      continue;
    }
    runs.push_back(std::move(results[i]));
  }
  json summary = FolderSummary(identity, std::move(runs), n, Stopped(options), sim_failed);
  WriteSummary(dir, summary);
  record({"summary.json"});
  manifest.Write(dir);  // one sorted line per file
  return summary;
}

}  // namespace fnmpc::experiment

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
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {

namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

double NumberOr(const json& j, const char* key, double fallback) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : fallback;
}
bool Stopped(const RunFolderOptions& o) { return o.stop != nullptr && *o.stop != 0; }
std::string RunDir(int r) { return fmt::format("run-{:02d}", r + 1); }

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

const char* const kShardKey = "shard";
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

namespace {
/// Why `--overwrite` refuses a folder without a manifest, and what to do.
std::string NoManifest(const std::string& dir) {
  return fmt::format(
      "{}: --overwrite deletes only files fnmpc wrote, and this folder has no {} listing "
      "them: it is not a folder of fnmpc (or one written by an earlier fnmpc, which "
      "kept no manifest); nothing deleted: delete it yourself or choose another -o",
      dir, kManifestName);
}
}  // namespace

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

namespace {
/// `p` absolute and normal, symbolic links resolved where the path exists.
fs::path Resolved(const std::string& p) { return fs::weakly_canonical(fs::absolute(p)); }
/// `inner` is `outer` or lies below it.
bool Within(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

/// The merge's -o: not one of the shards nor inside one (nor holding one); new, empty, or,
/// with `overwrite`, a folder fnmpc wrote that holds nothing its manifest does not list.
/// Returns the folder to write (symbolic links resolved) and whether it is to be replaced.
std::pair<fs::path, bool> CheckMergeTarget(const std::vector<std::string>& shards,
                                           const std::string& out, bool overwrite) {
  const fs::path target = Resolved(out);
  for (const std::string& shard : shards) {
    const fs::path s = Resolved(shard);
    if (Within(target, s)) {
      throw std::runtime_error(fmt::format(
          "merge: -o {} is the shard folder {} or lies inside it: a merge never writes into "
          "its own input; choose another -o",
          out, shard));
    }
    if (Within(s, target)) {
      throw std::runtime_error(fmt::format(
          "merge: the shard folder {} lies inside -o {}: choose another -o", shard, out));
    }
  }
  std::error_code ec;
  if (!fs::exists(target, ec)) return {target, false};
  if (!fs::is_directory(target, ec)) throw std::runtime_error(out + ": exists and is not a folder");
  if (fs::is_empty(target, ec)) return {target, false};
  if (!overwrite) {
    throw std::runtime_error(out +
                             ": not empty (an earlier merge?); use --overwrite to replace it or "
                             "choose another -o");
  }
  if (!FolderManifest::Exists(out)) throw std::runtime_error(NoManifest(out));
  const std::vector<std::string> extra = UnlistedFiles(out, FolderManifest::Read(out));
  if (!extra.empty()) {
    throw std::runtime_error(fmt::format(
        "{}: holds {} file(s) fnmpc did not write ({}{}): --overwrite replaces a merged folder "
        "only when it holds nothing else; nothing deleted: move them away or choose another -o",
        out, extra.size(), extra.front(), extra.size() > 1 ? ", ..." : ""));
  }
  return {target, true};
}

/// Every file the shard's manifest lists is there, finished, with its size and digest.
FolderManifest VerifiedShard(const std::string& dir) {
  if (!FolderManifest::Exists(dir)) {
    throw std::runtime_error(fmt::format(
        "{}: no {}: not a shard folder of `fnmpc run --shard` (or one of an earlier fnmpc, "
        "which kept no manifest); fly the shard again",
        dir, kManifestName));
  }
  FolderManifest m = FolderManifest::Read(dir);
  for (const auto& [path, e] : m.entries()) {
    const std::string file = dir + "/" + path;
    if (!e.finished()) {
      throw std::runtime_error(file +
                               ": not finished (the shard was stopped while writing it); "
                               "resume the shard (fnmpc run ... --resume) before merging");
    }
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) {
      throw std::runtime_error(fmt::format(
          "{}: missing (listed in {}): the shard folder is damaged; fly the shard again", file,
          kManifestName));
    }
    const auto size = static_cast<std::int64_t>(fs::file_size(file, ec));
    if (ec || size != e.size) {
      throw std::runtime_error(fmt::format(
          "{}: {} bytes, {} when fnmpc wrote it: truncated or changed; fly the shard again", file,
          size, e.size));
    }
    if (FileSha256(file) != e.sha256) {
      throw std::runtime_error(fmt::format(
          "{}: its SHA-256 differs from the one fnmpc recorded in {}: changed since it was "
          "written; fly the shard again",
          file, kManifestName));
    }
  }
  return m;
}

/// A temporary folder of our own beside `target` (created here, so nobody else's).
fs::path NewFolderBeside(const fs::path& target, const char* what) {
  fs::create_directories(target.parent_path());
  for (int k = 0;; ++k) {
    const fs::path p =
        target.parent_path() / fmt::format(".{}.{}-{}-{}", target.filename().string(), what,
                                           static_cast<long>(::getpid()), k);
    if (fs::create_directory(p)) return p;
  }
}

json Merge(const std::vector<std::string>& shards, const std::string& out, bool overwrite);
}  // namespace

json MergeRunFolders(const std::vector<std::string>& shards, const std::string& out,
                     bool overwrite) {
  try {
    return Merge(shards, out, overwrite);
  } catch (const fs::filesystem_error& e) {
    // A message of ours, never the library's "filesystem error: ..." text.
    std::string paths = e.path1().string();
    if (!e.path2().empty()) paths += " -> " + e.path2().string();
    throw std::runtime_error(
        fmt::format("merge: {}: {}; -o {} left as it was", paths, e.code().message(), out));
  }
}

namespace {
json Merge(const std::vector<std::string>& shards, const std::string& out, bool overwrite) {
  if (shards.empty()) throw std::runtime_error("merge: no shard folders given");
  const auto [target, replace] = CheckMergeTarget(shards, out, overwrite);
  std::vector<json> summaries;
  std::vector<FolderManifest> manifests;
  for (const std::string& dir : shards) {
    manifests.push_back(VerifiedShard(dir));
    summaries.push_back(ReadJson(config::PathInside(dir, "summary.json")));
  }
  // One experiment: the same identity and scenario file in every shard, every shard once.
  const json& first = summaries.front();
  if (!first.contains(kShardKey) || !first[kShardKey].is_string()) {
    throw std::runtime_error(config::PathInside(shards.front(), "summary.json") +
                             ": key 'shard': missing: not a shard folder (fnmpc run --shard)");
  }
  const Shard s0 = ParseShard(first[kShardKey].get<std::string>());
  const std::string scenario_text = ReadText(config::PathInside(shards.front(), "scenario.yaml"));
  std::vector<std::string> folder_of(static_cast<std::size_t>(s0.count));
  json identity;
  for (const char* key : {"scenario", "scenario_file", "runs_requested", "first_seed", "duration_s",
                          "reality", "downwash", "compensation", "timing"}) {
    if (!first.contains(key)) {
      throw std::runtime_error(config::PathInside(shards.front(), "summary.json") + ": key '" +
                               key + "': missing");
    }
    identity[key] = first[key];
  }
  for (std::size_t i = 0; i < shards.size(); ++i) {
    const json& s = summaries[i];
    const std::string path = config::PathInside(shards[i], "summary.json");
    const Shard shard = ParseShard(s.value(kShardKey, std::string("missing")));
    if (shard.count != s0.count) {
      throw std::runtime_error(fmt::format("{}: key 'shard': {}/{}, but {} is one of {}", path,
                                           shard.index, shard.count, shards.front(), s0.count));
    }
    for (const auto& [key, value] : identity.items()) {
      if (!s.contains(key) || s[key] != value) {
        throw std::runtime_error(fmt::format("{}: key '{}': {}, but {} in {}: not one experiment",
                                             path, key, s.contains(key) ? s[key].dump() : "missing",
                                             value.dump(), shards.front()));
      }
    }
    if (ReadText(config::PathInside(shards[i], "scenario.yaml")) != scenario_text) {
      throw std::runtime_error(config::PathInside(shards[i], "scenario.yaml") + ": differs from " +
                               config::PathInside(shards.front(), "scenario.yaml"));
    }
    std::string& slot = folder_of[static_cast<std::size_t>(shard.index)];
    if (!slot.empty()) {
      throw std::runtime_error(fmt::format("{}: shard {}/{} given twice (also {})", shards[i],
                                           shard.index, shard.count, slot));
    }
    slot = shards[i];
  }
  for (int i = 0; i < s0.count; ++i) {
    if (folder_of[static_cast<std::size_t>(i)].empty()) {
      throw std::runtime_error(fmt::format("merge: shard {}/{} is missing", i, s0.count));
    }
  }
  const int total_runs = identity["runs_requested"].get<int>();
  // Every run there and complete, taken in run order.
  std::vector<json> runs(static_cast<std::size_t>(total_runs));
  const std::uint64_t seed0 = identity["first_seed"].get<std::uint64_t>();
  for (std::size_t i = 0; i < shards.size(); ++i) {
    for (const json& run : summaries[i].value("run_summaries", json::array())) {
      const std::string d = run.value("dir", std::string());
      int r = -1;
      if (d.size() > 4) std::from_chars(d.data() + 4, d.data() + d.size(), r);
      if (r < 1 || r > total_runs) {
        throw std::runtime_error(config::PathInside(shards[i], "summary.json") + ": run '" + d +
                                 "' is not one of the experiment's");
      }
      runs[static_cast<std::size_t>(r - 1)] = run;
    }
  }
  for (int r = 0; r < total_runs; ++r) {
    const json& run = runs[static_cast<std::size_t>(r)];
    const std::string shard = folder_of[static_cast<std::size_t>(r % s0.count)];
    if (run.is_null() || !run.value("complete", false) || run.contains("error")) {
      throw std::runtime_error(fmt::format(
          "merge: {} (seed {}) of shard {}: {}; rerun the shard (fnmpc run ... --resume) "
          "before merging",
          RunDir(r), seed0 + static_cast<std::uint64_t>(r), shard,
          run.is_null()           ? "not flown"
          : run.contains("error") ? "the simulation stopped: " + run["error"].get<std::string>()
                                  : std::string("not complete (interrupted)")));
    }
  }
  // Every run's files listed (and so checked above): its summary and a CSV per vehicle.
  for (int r = 0; r < total_runs; ++r) {
    const std::size_t s = static_cast<std::size_t>(r % s0.count);
    const auto i = static_cast<std::size_t>(std::find(shards.begin(), shards.end(), folder_of[s]) -
                                            shards.begin());
    const json& vehicles = runs[static_cast<std::size_t>(r)].value("vehicles", json::object());
    std::vector<std::string> needed{RunDir(r) + "/summary.json"};
    for (const auto& [name, v] : vehicles.items())
      needed.push_back(RunDir(r) + "/" + name + ".csv");
    for (const std::string& f : needed) {
      if (manifests[i].entries().count(f) == 0) {
        throw std::runtime_error(fmt::format(
            "{}/{}: missing (the summary names {} (seed {}), the manifest lists no such file): "
            "the shard folder is damaged; fly the shard again",
            folder_of[s], f, RunDir(r), seed0 + static_cast<std::uint64_t>(r)));
      }
    }
  }
  json summary = FolderSummary(identity, runs, total_runs, false, false);
  // Everything is checked: the merge is written into a folder of its own beside -o and
  // renamed into place, so -o is the earlier folder or the whole new one, never a part.
  const fs::path tmp = NewFolderBeside(target, "merge");
  const std::string t = tmp.string();
  try {
    FolderManifest merged;
    config::WriteFileAtomically(config::PathInside(t, "scenario.yaml"), scenario_text);
    merged.Record(t, "scenario.yaml");
    for (int r = 0; r < total_runs; ++r) {
      const std::size_t s = static_cast<std::size_t>(r % s0.count);
      const auto i = static_cast<std::size_t>(
          std::find(shards.begin(), shards.end(), folder_of[s]) - shards.begin());
      fs::create_directory(tmp / RunDir(r));
      for (const auto& [path, e] : manifests[i].entries()) {
        if (!path.starts_with(RunDir(r) + "/")) continue;
        const std::string bytes = ReadText(folder_of[s] + "/" + path);
        if (TextSha256(bytes) != e.sha256) {
          throw std::runtime_error(folder_of[s] + "/" + path + ": changed while merging");
        }
        config::WriteFileAtomically(t + "/" + path, bytes);
        merged.Record(t, path);
        if (merged.entries().at(path).sha256 != e.sha256) {
          throw std::runtime_error(t + "/" + path + ": the copy differs from its shard's file");
        }
      }
    }
    WriteSummary(t, summary);
    merged.Record(t, "summary.json");
    merged.Write(t);
    if (!replace) {
      std::error_code ec;
      fs::remove(target, ec);  // an empty folder (or none)
      fs::rename(tmp, target);
    } else {
      // The earlier folder is moved aside, the new one renamed into place, and only then the
      // earlier one's listed files deleted.
      const FolderManifest old_manifest = FolderManifest::Read(target.string());
      if (!UnlistedFiles(target.string(), old_manifest).empty()) {
        throw std::runtime_error(out + ": a file fnmpc did not write appeared during the merge");
      }
      const fs::path old = NewFolderBeside(target, "old");
      fs::remove(old);
      fs::rename(target, old);
      try {
        fs::rename(tmp, target);
      } catch (...) {
        fs::rename(old, target);
        throw;
      }
      DeleteListedFiles(old.string(), old_manifest);
      std::error_code ec;
      fs::remove(config::PathInside(old.string(), kManifestName), ec);
      if (!fs::remove(old, ec)) {
        fmt::print(stderr,
                   "fnmpc merge: warning: {} (the earlier {}) is not empty; left as it is\n",
                   old.string(), out);
      }
    }
  } catch (const fs::filesystem_error&) {
    std::error_code ec;
    fs::remove_all(tmp, ec);  // ours alone: made above, filled by this merge
    throw;                    // MergeRunFolders names its paths
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw std::runtime_error(fmt::format("merge: {}; -o {} left as it was", e.what(), out));
  }
  return summary;
}
}  // namespace

}  // namespace fnmpc::experiment

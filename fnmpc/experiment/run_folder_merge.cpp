// SPDX-License-Identifier: BSD-3-Clause
// MergeRunFolders (run_folder.hpp): shards of one folder, checked against their manifests,
// merged into one folder as if it had been flown in one go.
#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <stdexcept>
#include <vector>

#include "fnmpc/config/output_files.hpp"
#include "fnmpc/experiment/folder_manifest.hpp"
#include "fnmpc/experiment/run_folder.hpp"
#include "fnmpc/experiment/run_folder_detail.hpp"

namespace fnmpc::experiment {

namespace fs = std::filesystem;
using json = nlohmann::json;
using namespace run_folder_detail;  // NOLINT: the helpers shared with run_folder.cpp

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

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <csignal>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"

/// The runs of a run folder as `fnmpc run` does them (scenario.yaml, run-NN/ with one CSV
/// per vehicle and a summary.json per run, the aggregated summary.json); shared by the CLI
/// and the Python module so both produce the same folder for the same seed.
namespace fnmpc::experiment {

/// A deterministic slice of a folder's runs: run r (0-based) belongs to shard r % count.
/// `sharded` false: the whole folder (no "shard" key); a shard 0/1 is a shard folder all the
/// same (mergeable on its own).
struct Shard {
  int index = 0;
  int count = 1;
  bool sharded = false;
  [[nodiscard]] bool Has(int run) const { return run % count == index; }
  [[nodiscard]] bool whole() const { return !sharded; }
};
/// Parses "I/N" (0 <= I < N <= 10000); std::invalid_argument naming the text otherwise.
Shard ParseShard(const std::string& text);

struct RunFolderOptions {
  int runs = 1;               ///< runs with seeds seed, seed + 1, ...
  int jobs = 1;               ///< runs flown at the same time (>= 1)
  int threads = 1;            ///< threads per run for its vehicles (RunOptions::threads, >= 1)
  std::int64_t seed = -1;     ///< first seed; < 0: the scenario's
  bool progress = false;      ///< progress and one result line per run on stderr
  std::string scenario_file;  ///< copied to <dir>/scenario.yaml when it names a file
  /// Set (non-zero) from a signal handler to stop: the current run writes what it has and
  /// the summary is marked incomplete ("stopped": "interrupted"). nullptr: never.
  const volatile std::sig_atomic_t* stop = nullptr;
  /// Fly only this shard's runs; the folder then holds those run-NN/ and a summary with
  /// "shard": "I/N", to be joined by MergeRunFolders.
  Shard shard;
  /// Keep the runs of an earlier, interrupted attempt in the folder whose run-NN/summary.json
  /// says "complete": true, fly only the others (the folder must be this one's: the caller
  /// checks with CheckResumable).
  bool resume = false;
  bool timing = true;  ///< RunOptions::timing: false for a folder that depends on seeds alone
};

/// Creates a run folder or makes an existing one ready: `dir` must be new or empty; with
/// `overwrite`, a folder fnmpc wrote (its .fnmpc-manifest, folder_manifest.hpp) loses the
/// files the manifest lists and nothing else (a user's own files stay; the folder itself is
/// kept, so a symlink to it stays). A folder without a manifest is refused, nothing deleted.
/// Then an empty manifest marks the folder as fnmpc's. std::runtime_error naming `dir`.
void PrepareRunFolder(const std::string& dir, bool overwrite);

/// The settings that make two run folders the same experiment (the summary's keys
/// "scenario", "scenario_file", "runs_requested", "first_seed", "duration_s", "reality",
/// "downwash", "compensation", "timing"), as RunFolder writes them.
nlohmann::json FolderIdentity(const config::ScenarioConfig& scenario,
                              const RunFolderOptions& options);

/// For RunFolderOptions::resume: `dir` must be new, empty, or hold a summary.json with the same
/// FolderIdentity and shard and a scenario.yaml equal to options.scenario_file byte for byte.
/// std::runtime_error naming the file and the key that differs otherwise.
void CheckResumable(const config::ScenarioConfig& scenario, const RunFolderOptions& options,
                    const std::string& dir);

/// Runs the simulations into the existing folder `dir` (up to `jobs` at a time; the folder
/// and summary are the same as with one job: each run depends only on its seed) and writes
/// <dir>/summary.json atomically: AggregateRuns plus `scenario_file`, `runs_requested` and
/// `complete` (false when stopped, when the simulator failed, which ends the folder after that run,
/// or when fewer runs than requested were done). Returns that summary. Throws std::invalid_argument
/// on runs < 1, jobs < 1 or threads < 1 and std::runtime_error when the folder cannot be written.
nlohmann::json RunFolder(const config::ScenarioConfig& scenario, const RunFolderOptions& options,
                         const std::string& dir);

/// Joins the shard folders of one experiment (RunFolderOptions::shard) into `out`: their
/// run-NN/ copied, scenario.yaml, and the summary.json the unsharded RunFolder writes for the
/// same runs, so with RunFolderOptions::timing off the folder (manifest included) equals the
/// unsharded one byte for byte. Everything is checked before `out` is touched: every shard's
/// manifest (every listed file there, finished, with its size and SHA-256), every run of its
/// summary listed with its CSVs; `out` is neither a shard nor inside one; a non-empty `out`
/// needs `overwrite` and a manifest listing all it holds. The folder is written beside `out`
/// and renamed into place (an earlier merge replaced only then). Throws std::runtime_error,
/// leaving `out` as it was, when the shards are not one experiment (a differing identity key,
/// scenario.yaml, shard count), a shard is missing, given twice or damaged, a run is missing
/// or not complete (named with its shard folder and seed), or a file cannot be written.
/// Returns the summary.
nlohmann::json MergeRunFolders(const std::vector<std::string>& shards, const std::string& out,
                               bool overwrite = false);

}  // namespace fnmpc::experiment

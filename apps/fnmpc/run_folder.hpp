// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <csignal>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "fnmpc/config/scenario_yaml.hpp"

/// The runs of a run folder as `fnmpc run` does them (scenario.yaml, run-NN/ with one CSV
/// per vehicle and a summary.json per run, the aggregated summary.json); shared by the CLI
/// and the Python module so both produce the same folder for the same seed.
namespace fnmpc::app {

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
};

/// Runs the simulations into the existing folder `dir` (up to `jobs` at a time; the folder
/// and summary are the same as with one job: each run depends only on its seed) and writes
/// <dir>/summary.json atomically: AggregateRuns plus `scenario_file`, `runs_requested` and
/// `complete` (false when stopped, when the simulator failed, which ends the folder after that run,
/// or when fewer runs than requested were done). Returns that summary. Throws std::invalid_argument
/// on runs < 1, jobs < 1 or threads < 1 and std::runtime_error when the folder cannot be written.
nlohmann::json RunFolder(const config::ScenarioConfig& scenario, const RunFolderOptions& options,
                         const std::string& dir);

}  // namespace fnmpc::app

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"

/// Closed loop of a formation scenario: MuJoCo World (1 ms physics, all sensors) plus one
/// formation::VehicleController per flying vehicle (every Ts), CSV logs and metrics.
namespace fnmpc::app {

/// Options of one run.
struct RunOptions {
  std::uint64_t seed = 1;  ///< noise seed of the world (and of the manual leader's walk)
  double duration = -1.0;  ///< simulated time [s]; < 0: the scenario's
  bool progress = false;   ///< print progress to stderr
  std::string label;       ///< progress prefix
};

/// Runs one closed-loop simulation of `scenario`, writes one CSV log per vehicle
/// (<dir>/<vehicle>.csv) and returns the run's metrics (also written to
/// <dir>/summary.json). Throws std::runtime_error when the output cannot be written.
nlohmann::json RunScenario(const config::ScenarioConfig& scenario, const RunOptions& options,
                           const std::string& dir);

/// Aggregates per-run summaries: the mean over runs of each mean-type metric, the worst run
/// of each max, min or flag, and the list of runs.
nlohmann::json AggregateRuns(const std::vector<nlohmann::json>& runs);

/// Returns a copy of `scenario` shortened to `duration` [s]: the leader's trajectory and the
/// landing are compressed so that the run still takes off, flies and lands.
config::ScenarioConfig Shortened(const config::ScenarioConfig& scenario, double duration);

}  // namespace fnmpc::app

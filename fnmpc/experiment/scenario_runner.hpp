// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <csignal>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/run_log.hpp"
#include "fnmpc/formation/trajectory.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/onboard/controller_setup.hpp"
#include "fnmpc/sim/world.hpp"

/// Closed loop of a formation scenario: MuJoCo World (1 ms physics, all sensors) plus one
/// formation::VehicleController per flying vehicle (every Ts), CSV logs and metrics.
namespace fnmpc::experiment {

/// The world: every vehicle resting at its start, noise seeded from `seed`; with the
/// scenario's reality on, ApplyReality's true plants and wind.
sim::WorldConfig WorldConfigFor(const config::ScenarioConfig& scenario, std::uint64_t seed);
/// Reality (docs/simulator.md "Reality") on a world built from `scenario`: each vehicle's true
/// plant (its `plant_file`, else drawn by model::DrawTruePlant for (seed, vehicle index) from
/// the spread of `reality.plant`) and the wind of `reality.wind`.
void ApplyReality(const config::ScenarioConfig& scenario, std::uint64_t seed,
                  sim::WorldConfig* world);

/// Options of one run.
struct RunOptions {
  std::uint64_t seed = 1;  ///< noise seed of the world (and of the manual leader's walk)
  double duration = -1.0;  ///< simulated time [s]; < 0: the scenario's
  bool progress = false;   ///< print progress to stderr
  std::string label;       ///< progress prefix
  /// Threads flying the vehicles' estimators and controllers of one control step (>= 1); the
  /// run is the same bit for bit whatever the count (timing columns aside).
  int threads = 1;
  /// false: no wall-clock solver times (NaN in the CSVs, null in the summaries), so the run
  /// folder depends on the seed alone, bit for bit (`fnmpc run --timing off`).
  bool timing = true;
  /// When given and set (a signal handler), the run stops after the current physics step,
  /// writes what is complete and returns a summary with "complete": false.
  const volatile std::sig_atomic_t* stop = nullptr;
};

/// Runs one closed-loop simulation of `scenario`, writes one CSV log per vehicle
/// (<dir>/<vehicle>.csv) and returns the run's metrics (also written to
/// <dir>/summary.json, atomically). The summary's "complete" is false when the run was
/// stopped (options.stop: "stopped": "interrupted") or the simulator became unstable
/// ("error": the SimulationError with the state at that moment); the CSVs then hold every
/// step simulated. "failures" lists, per vehicle, why the run failed (left the envelope,
/// never took off, not landed safely, failsafe); "warnings" the scenario's warnings.
/// Throws std::runtime_error naming the file and the errno text when output cannot be written.
nlohmann::json RunScenario(const config::ScenarioConfig& scenario, const RunOptions& options,
                           const std::string& dir);

/// Aggregates per-run summaries: the mean over runs of each mean-type metric, the worst run
/// of each max, min or flag, and the list of runs.
nlohmann::json AggregateRuns(const std::vector<nlohmann::json>& runs);

/// Returns a copy of `scenario` shortened to `duration` [s] (`fnmpc run --duration`): the
/// landing moves earlier by the time cut, keeping the scenario's landing allowance (duration
/// minus phases.landing_time); every vehicle's own landing_time moves with it (in proportion
/// inside the leader's flight, by the cut after the scenario's landing, not at all before the
/// leader starts); the leader keeps the legs (moves) it finishes by the new landing, at least
/// one. Throws config::ConfigError naming --duration when the landing would not come after the
/// leader's start.
config::ScenarioConfig Shortened(const config::ScenarioConfig& scenario, double duration);

}  // namespace fnmpc::experiment

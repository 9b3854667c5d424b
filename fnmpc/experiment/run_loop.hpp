// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

#include "fnmpc/experiment/run_record.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {

/// The closed loop of RunScenario: the world (1 ms physics, all sensors, the autopilots'
/// command-timeout failsafe on), one controller per flying vehicle every sample time, the
/// scenario's faults applied; writes <dir>/<vehicle>.csv (and the plant files with reality
/// on) and returns what the metrics need. Stops early on options.stop or a simulator error
/// (RunRecord::stopped, sim_error).
RunRecord RunClosedLoop(const config::ScenarioConfig& sc, const RunOptions& options,
                        const std::string& dir);

}  // namespace fnmpc::experiment

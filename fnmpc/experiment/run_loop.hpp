// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

#include "fnmpc/experiment/run_record.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {

/// Flies the scenario in a ClosedLoop (closed_loop.hpp) with the observers of `fnmpc run`
/// (run_observers.hpp): writes <dir>/<vehicle>.csv (and the plant files with reality on) and
/// returns what the metrics need. Stops early on options.stop or a simulator error
/// (RunRecord::stopped, sim_error).
RunRecord RecordRun(const config::ScenarioConfig& sc, const RunOptions& options,
                    const std::string& dir);

}  // namespace fnmpc::experiment

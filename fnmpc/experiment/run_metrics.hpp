// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fnmpc/experiment/run_record.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

namespace fnmpc::experiment {

/// The metrics of one run (summary.json, docs/scenarios.md "Run folder and metrics") from
/// what the closed loop recorded: per vehicle, per fault, the failures and the top-level
/// figures. `fault_lines` gets one line per fault for stderr.
nlohmann::json RunSummary(const config::ScenarioConfig& sc, const RunOptions& options,
                          const RunRecord& record, std::vector<std::string>* fault_lines);

}  // namespace fnmpc::experiment

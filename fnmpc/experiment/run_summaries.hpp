// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fnmpc/experiment/run_record.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"

/// The parts of summary.json, one summariser per record of the run (RunSummary puts them
/// together, run_metrics.hpp): the vehicles, the faults and the failures.
namespace fnmpc::experiment {

inline double Median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}
inline double Max(const std::vector<double>& v) {
  return v.empty() ? kNaN : *std::max_element(v.begin(), v.end());
}
inline double Mean(const std::vector<double>& v) {
  if (v.empty()) return kNaN;
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}
/// NaN -> null in JSON.
inline nlohmann::json Num(double x) {
  return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr);
}

/// Totals over the vehicles that the run's top-level figures are made of.
struct VehicleTotals {
  double steady_worst = kNaN, mean_worst = kNaN, max_worst = kNaN;
  double flight_mean_worst = kNaN, flight_max_worst = kNaN;
  std::vector<double> all_times;  ///< every solver time of every vehicle [s]
  double time_max = 0.0, time_max_first = 0.0;
  long fallbacks = 0, failures = 0, over_budget = 0, nmpc_steps = 0, guarded = 0;
  long recoveries = 0, failsafes = 0, leaderless_landings = 0;
  bool landed_safely = true;
};

/// Counts of the failure kinds that summary.json reports at the top level.
struct FailureCounts {
  long collisions = 0, ground_strikes = 0, hard_touchdowns = 0;
};

/// `vehicles`: per vehicle its formation or tracking errors, solver statistics, recoveries,
/// landing, envelope and separation; the totals over the vehicles into `totals`.
nlohmann::json SummariseVehicles(const config::ScenarioConfig& sc, const RunOptions& options,
                                 const RunRecord& record, VehicleTotals* totals);
/// `faults`: what happened, per fault of the scenario; the vehicles a fault took down into
/// `downed_by`, one line per fault into `fault_lines`.
nlohmann::json SummariseFaults(const config::ScenarioConfig& sc, const RunRecord& record,
                               const nlohmann::json& vehicles, const VehicleTotals& totals,
                               std::vector<int>* downed_by, std::vector<std::string>* fault_lines);
/// `failures`: why the run must not count as a success (collisions, envelope, take-off,
/// failsafe, ground strikes, hard touchdowns, not landed), per vehicle.
nlohmann::json SummariseFailures(const config::ScenarioConfig& sc, const RunRecord& record,
                                 const nlohmann::json& vehicles, const std::vector<int>& downed_by,
                                 bool complete, FailureCounts* counts);

}  // namespace fnmpc::experiment

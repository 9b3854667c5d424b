// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/run_metrics.hpp"

#include <algorithm>
#include <cmath>

#include "fnmpc/experiment/run_summaries.hpp"

namespace fnmpc::experiment {

using json = nlohmann::json;

// summary.json of one run: the per-record summarisers (run_summaries.hpp) and the top-level
// figures over them.
json RunSummary(const config::ScenarioConfig& sc, const RunOptions& options, const RunRecord& r,
                std::vector<std::string>* fault_lines) {
  const config::ScenarioFaults& faults = sc.faults;
  VehicleTotals T;
  const json vehicles = SummariseVehicles(sc, options, r, &T);
  std::vector<int> downed_by;  // vehicles a fault took down (kill, motors off)
  const json fj = SummariseFaults(sc, r, vehicles, T, &downed_by, fault_lines);
  const bool complete = r.stopped.empty() && r.sim_error.empty();
  FailureCounts C;
  const json failures = SummariseFailures(sc, r, vehicles, downed_by, complete, &C);

  json s;
  s["scenario"] = sc.name;
  s["complete"] = complete;
  if (!r.stopped.empty()) s["stopped"] = r.stopped;
  if (!r.sim_error.empty()) s["error"] = r.sim_error;
  s["failures"] = failures;
  s["warnings"] = sc.warnings;
  s["seed"] = options.seed;
  s["duration_s"] = r.duration;
  s["downwash"] = sc.downwash;
  s["reality"] = sc.reality.enabled;
  s["compensation"] = formation::ToString(sc.compensation);
  if (r.link) {
    const LinkStatistics& l = r.link_stats;
    s["link"] = {{"latency_s", sc.link.latency},
                 {"loss_rate", sc.link.loss_rate},
                 {"bandwidth_bit_s", sc.link.bandwidth},
                 {"plan_timeout_s", sc.plan_timeout},
                 {"sent", l.sent},
                 {"addressed", l.addressed},
                 {"delivered", l.delivered},
                 {"lost", l.lost},
                 {"late", l.late}};
  }
  // The scenario's default window; a follower with its own landing_time uses its own
  // (vehicles.<name>.formation_window_s).
  s["formation_window_s"] = {sc.trajectory_start, sc.landing_time};
  s["steady_state_formation_error_m"] = Num(T.steady_worst);
  s["mean_formation_error_m"] = Num(T.mean_worst);
  s["max_formation_error_m"] = Num(T.max_worst);
  s["mean_formation_error_flight_m"] = Num(T.flight_mean_worst);
  s["max_formation_error_flight_m"] = Num(T.flight_max_worst);
  s["solver_time_max_s"] = options.timing ? Num(T.time_max) : json(nullptr);
  s["solver_time_max_after_first_step_s"] = options.timing ? Num(T.time_max_first) : json(nullptr);
  s["solver_time_median_s"] = Num(Median(T.all_times));
  s["solver_steps_over_budget_share"] =
      !options.timing ? json(nullptr)
      : T.nmpc_steps > 0
          ? json(static_cast<double>(T.over_budget) / static_cast<double>(T.nmpc_steps))
          : json(0.0);
  s["sample_time_s"] = sc.rti.sample_time;
  s["nmpc_steps"] = T.nmpc_steps;
  s["fallbacks"] = T.fallbacks;
  s["recoveries"] = T.recoveries;
  s["failsafes"] = T.failsafes;
  s["leaderless_landings"] = T.leaderless_landings;
  s["solver_failures"] = T.failures;
  s["solver_converged_every_step"] = T.failures == 0 && T.fallbacks == 0 && T.nmpc_steps > 0;
  s["guarded_commands"] = T.guarded;
  s["min_separation_m"] = Num(r.min_separation);
  s["min_separation_pair"] = r.min_separation_pair[0] >= 0
                                 ? json{sc.vehicles[r.min_separation_pair[0]].name,
                                        sc.vehicles[r.min_separation_pair[1]].name}
                                 : json(nullptr);
  s["min_separation_time_s"] = Num(r.min_separation_time);
  s["collision_distance_m"] = sc.metrics.collision_distance;
  s["collisions"] = C.collisions;
  s["ground_strikes"] = C.ground_strikes;
  s["hard_touchdowns"] = C.hard_touchdowns;
  s["landed_safely"] = T.landed_safely;
  s["vehicles"] = vehicles;
  if (faults.any()) s["faults"] = fj;
  return s;
}

json AggregateRuns(const std::vector<json>& runs) {
  json a;
  if (runs.empty()) return a;
  auto values = [&runs](const std::string& key) {
    std::vector<double> v;
    for (const json& r : runs) {
      if (r.contains(key) && r[key].is_number()) v.push_back(r[key].get<double>());
    }
    return v;
  };
  a["scenario"] = runs.front()["scenario"];
  a["runs"] = runs.size();
  for (const char* k : {"steady_state_formation_error_m", "mean_formation_error_m",
                        "solver_time_median_s", "solver_steps_over_budget_share"}) {
    a[k] = Num(Mean(values(k)));
  }
  for (const char* k :
       {"max_formation_error_m", "max_formation_error_flight_m", "mean_formation_error_flight_m",
        "solver_time_max_s", "solver_time_max_after_first_step_s", "fallbacks", "recoveries",
        "failsafes", "leaderless_landings", "solver_failures", "guarded_commands", "collisions",
        "ground_strikes", "hard_touchdowns"}) {
    a[k] = Num(Max(values(k)));
  }
  {
    const auto v = values("min_separation_m");
    a["min_separation_m"] = v.empty() ? json(nullptr) : json(*std::min_element(v.begin(), v.end()));
  }
  a["steady_state_formation_error_worst_run_m"] =
      Num(Max(values("steady_state_formation_error_m")));
  bool landed = true, converged = true;
  for (const json& r : runs) {
    landed = landed && r.value("landed_safely", false);
    converged = converged && r.value("solver_converged_every_step", false);
  }
  a["landed_safely"] = landed;
  // Cooperative mode: the link's messages summed over the runs.
  if (runs.front().contains("link")) {
    json link = runs.front()["link"];
    for (const char* k : {"sent", "addressed", "delivered", "lost", "late"}) {
      long sum = 0;
      for (const json& r : runs) sum += r.contains("link") ? r["link"].value(k, 0L) : 0L;
      link[k] = sum;
    }
    a["link"] = link;
  }
  bool complete = true;
  json failures = json::array();
  for (std::size_t r = 0; r < runs.size(); ++r) {
    complete = complete && runs[r].value("complete", false);
    if (!runs[r].contains("failures")) continue;
    for (json f : runs[r]["failures"]) {
      f["run"] = runs[r].value("dir", std::to_string(r + 1));
      failures.push_back(f);
    }
  }
  a["complete"] = complete;
  a["failures"] = failures;
  a["warnings"] = runs.front().value("warnings", json::array());
  a["solver_converged_every_step"] = converged;
  a["sample_time_s"] = runs.front()["sample_time_s"];
  a["formation_window_s"] = runs.front()["formation_window_s"];
  a["aggregation"] =
      "means: mean over runs; max_*, solver_time_max_*, fallbacks, failures, collisions, "
      "ground_strikes, hard_touchdowns: worst run; "
      "min_separation_m: smallest; flags: all runs; link messages: sums";
  a["run_summaries"] = runs;
  return a;
}

}  // namespace fnmpc::experiment

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/run_metrics.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "fnmpc/formation/neighbour_thrust.hpp"
#include "fnmpc/onboard/formation_print.hpp"

namespace fnmpc::experiment {

namespace {

using json = nlohmann::json;

double Median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}
double Max(const std::vector<double>& v) {
  return v.empty() ? kNaN : *std::max_element(v.begin(), v.end());
}
double Mean(const std::vector<double>& v) {
  if (v.empty()) return kNaN;
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}
/// NaN -> null in JSON.
json Num(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

}  // namespace

json RunSummary(const config::ScenarioConfig& sc, const RunOptions& options, const RunRecord& r,
                std::vector<std::string>* fault_lines) {
  const bool manual = sc.leader_mode == "manual";
  const int nv = static_cast<int>(sc.vehicles.size());
  const config::ScenarioFaults& faults = sc.faults;
  // ---- Metrics.
  json vehicles = json::object();
  double steady_worst = kNaN, mean_worst = kNaN, max_worst = kNaN;
  double flight_mean_worst = kNaN, flight_max_worst = kNaN;
  std::vector<double> all_times;
  double time_max = 0.0, time_max_first = 0.0;
  long fallbacks = 0, failures = 0, over_budget = 0, nmpc_steps = 0, guarded = 0;
  long recoveries = 0, failsafes = 0, leaderless_landings = 0;
  bool landed_safely = true;
  auto worse = [](double a, double b) {
    return std::isnan(a) ? b : (std::isnan(b) ? a : std::max(a, b));
  };
  const std::vector<int> depth = onboard::TieDepths(sc);
  for (int i = 0; i < nv; ++i) {
    const auto& v = sc.vehicles[i];
    const VehicleRecord& L = r.vehicles[i];
    json j;
    j["role"] = v.leader ? "leader" : "follower";
    // Fewest formation ties from the leader (formation::TieDepths; null: not tied to it).
    j["depth"] = depth[static_cast<std::size_t>(i)] >= 0 ? json(depth[static_cast<std::size_t>(i)])
                                                         : json(nullptr);
    if (!v.leader) {
      j["formation_error_mean_m"] = Num(Mean(L.errors));
      j["formation_error_steady_state_mean_m"] = Num(Mean(L.steady_errors));
      j["formation_error_max_m"] = Num(Max(L.errors));
      j["formation_window_s"] = {sc.trajectory_start, config::LandingTime(sc, i)};
      j["formation_error_flight_mean_m"] = Num(Mean(L.flight_errors));
      j["formation_error_flight_max_m"] = Num(Max(L.flight_errors));
      j["steady_state_samples"] = L.steady_errors.size();
      json nbs = json::object();
      for (std::size_t n = 0; n < v.neighbours.size(); ++n) {
        nbs[v.neighbours[n].vehicle] = {{"mean_m", Num(Mean(L.nb_errors[n]))},
                                        {"steady_state_mean_m", Num(Mean(L.nb_steady[n]))},
                                        {"max_m", Num(Max(L.nb_errors[n]))}};
      }
      j["formation_error_by_neighbour"] = nbs;
      json order = json::array();  // CSV columns err0, err1 follow this order
      for (const auto& n : v.neighbours) order.push_back(n.vehicle);
      j["neighbours"] = order;
      steady_worst = worse(steady_worst, Mean(L.steady_errors));
      mean_worst = worse(mean_worst, Mean(L.errors));
      max_worst = worse(max_worst, Max(L.errors));
      flight_mean_worst = worse(flight_mean_worst, Mean(L.flight_errors));
      flight_max_worst = worse(flight_max_worst, Max(L.flight_errors));
    } else if (!manual) {
      j["tracking_error_mean_m"] = Num(Mean(L.tracking));
      j["tracking_error_max_m"] = Num(Max(L.tracking));
    }
    if (r.controlled[i]) {
      // Step 0 of the NMPC carries the initial convergence (Algorithm 1: iterate to KKT <
      // threshold); it is included in the max and reported apart.
      j["nmpc_steps"] = L.steps;
      j["solver_time_median_s"] = Num(Median(L.solver_time));
      j["solver_time_max_s"] = Num(Max(L.solver_time));
      j["solver_time_first_step_s"] = Num(L.first_step_time);
      j["solver_steps_over_budget_share"] =
          !options.timing ? json(nullptr)
          : L.steps > 0   ? json(static_cast<double>(L.over_budget) / static_cast<double>(L.steps))
                          : json(0.0);
      j["kkt_median"] = Num(Median(L.kkt));
      j["kkt_max"] = Num(Max(L.kkt));
      j["cost_median"] = Num(Median(L.cost));
      j["cost_max"] = Num(Max(L.cost));
      j["fallbacks"] = L.fallbacks;
      j["recoveries"] = L.reinitialisations;
      j["failsafes"] = std::isfinite(L.failsafe_time) ? 1 : 0;
      j["failsafe_time_s"] = Num(L.failsafe_time);
      j["failsafe_reason"] = L.failsafe_reason.empty() ? json(nullptr) : json(L.failsafe_reason);
      j["landing_site_shifts"] = L.landing_site_shifts;
      j["neighbour_departures"] = L.neighbour_departures;
      j["leaderless_landing_time_s"] = Num(L.tie_loss_time);
      j["leaderless_landing_reason"] =
          L.tie_loss_reason.empty() ? json(nullptr) : json(L.tie_loss_reason);
      recoveries += L.reinitialisations;
      failsafes += std::isfinite(L.failsafe_time) ? 1 : 0;
      leaderless_landings += std::isfinite(L.tie_loss_time) ? 1 : 0;
      j["solver_failures"] = L.failures;
      j["guarded_commands"] = L.guarded;
      {
        json b;  // wake level: neighbour thrust estimates bounded, by reason
        for (int k = 1; k < 4; ++k) {
          b[formation::ToString(static_cast<formation::ThrustBound>(k))] =
              L.neighbour_thrust_bounded[static_cast<std::size_t>(k)];
        }
        j["neighbour_thrust_bounded"] = b;
      }
      j["attitude_offset_bounded"] = L.attitude_offset_bounded;
      j["attitude_offset_deg"] = {Num(L.attitude_offset[0] * 180.0 / std::numbers::pi),
                                  Num(L.attitude_offset[1] * 180.0 / std::numbers::pi)};
      j["estimator_rejections"] = r.estimator_rejections[i];
      j["thrust_jump_at_switch_n"] = Num(L.max_thrust_jump_at_switch);
      const sim::TrueState& x = r.final_state[i];
      const double tilt =
          std::acos(std::clamp(std::cos(x.euler.x()) * std::cos(x.euler.y()), -1.0, 1.0));
      const bool touched = std::isfinite(L.touchdown_vz);
      // A vehicle that struck the ground in flight did not land safely, whatever its
      // touchdown afterwards (it may have been on the ground already).
      const bool ok =
          touched && L.motors_off && std::abs(L.touchdown_vz) < sc.metrics.touchdown_speed_max &&
          tilt < sc.metrics.max_tilt_landed && x.position.z() < sim::World::kRestHeight + 0.05 &&
          std::isnan(L.ground_strike_time);
      j["ground_strike_time_s"] = Num(L.ground_strike_time);
      j["ground_strike_vertical_speed_mps"] = Num(L.ground_strike_vz);
      j["ground_strike_phase"] =
          L.ground_strike_phase.empty() ? json(nullptr) : json(L.ground_strike_phase);
      j["touchdown_time_s"] = Num(L.touchdown_time);
      j["touchdown_vertical_speed_mps"] = Num(L.touchdown_vz);
      j["final_tilt_rad"] = tilt;
      j["motors_off_at_end"] = L.motors_off;
      j["landed_safely"] = ok;
      landed_safely = landed_safely && ok;
      all_times.insert(all_times.end(), L.solver_time.begin(), L.solver_time.end());
      time_max = worse(time_max, Max(L.solver_time));
      if (L.solver_time.size() > 1) {
        time_max_first = worse(time_max_first,
                               *std::max_element(L.solver_time.begin() + 1, L.solver_time.end()));
      }
      fallbacks += L.fallbacks;
      failures += L.failures;
      over_budget += L.over_budget;
      nmpc_steps += L.steps;
      guarded += L.guarded;
    } else {
      j["moved_by_hand"] = true;
    }
    j["max_altitude_m"] = Num(L.max_altitude);
    j["max_distance_from_start_m"] = L.max_distance;
    j["left_envelope_time_s"] = Num(L.envelope_time);
    j["min_separation_m"] = Num(L.min_separation);
    j["min_separation_to"] =
        L.min_separation_to >= 0 ? json(sc.vehicles[L.min_separation_to].name) : json(nullptr);
    j["min_separation_time_s"] = Num(L.min_separation_time);
    vehicles[v.name] = j;
  }
  // ---- Faults: what happened, per fault.
  json fj = json::object();
  std::vector<int> downed_by;  // vehicles a fault took down (kill, motors off)
  auto vec2 = [](const Vec3& p) { return p.allFinite() ? json{p.x(), p.y()} : json(nullptr); };
  if (faults.kill_controller.active()) {
    const int k = faults.kill_controller.index;
    downed_by.push_back(k);
    const sim::AutopilotStatus& ap = r.final_autopilot[k];
    const bool safe = vehicles[sc.vehicles[k].name].value("landed_safely", false);
    json j{{"vehicle", sc.vehicles[k].name},
           {"time_s", faults.kill_controller.time},
           {"autopilot_failsafe", ap.failsafe},
           {"autopilot_failsafe_time_s", Num(ap.failsafe_time)},
           {"autopilot_disarm_time_s", Num(ap.disarm_time)},
           {"touchdown_time_s", Num(r.downed[k].impact_time)},
           {"touchdown_vertical_speed_mps", Num(r.downed[k].impact_vz)},
           {"touchdown_position_m", vec2(r.downed[k].impact_position)},
           {"autopilot_landed", ap.disarmed_by_failsafe},
           {"landed_safely", safe}};
    // The other followers that had it as a neighbour: when it left their cost and their
    // errors to every neighbour after the kill and after the drop (window, steady state).
    json others = json::object();
    for (int i = 0; i < nv; ++i) {
      const auto& v = sc.vehicles[i];
      if (i == k || v.leader) continue;
      bool sees = false;
      for (const auto& n : v.neighbours) sees = sees || n.index == k;
      if (!sees) continue;
      const auto& smp = r.vehicles[i].samples;
      double dropped = kNaN;
      for (const auto& q : smp) {
        if (q.t >= faults.kill_controller.time &&
            q.active < static_cast<int>(v.neighbours.size())) {
          dropped = q.t;
          break;
        }
      }
      json errs = json::object();
      for (std::size_t n = 0; n < v.neighbours.size() && n < 2; ++n) {
        std::vector<double> after_kill, after_drop, after_kill_all;
        for (const auto& q : smp) {
          if (q.t < faults.kill_controller.time) continue;
          after_kill_all.push_back(q.err[n]);
          if (q.steady) after_kill.push_back(q.err[n]);
          if (q.steady && std::isfinite(dropped) && q.t >= dropped) after_drop.push_back(q.err[n]);
        }
        errs[v.neighbours[n].vehicle] = {{"mean_after_kill_m", Num(Mean(after_kill_all))},
                                         {"max_after_kill_m", Num(Max(after_kill_all))},
                                         {"steady_state_mean_after_kill_m", Num(Mean(after_kill))},
                                         {"steady_state_mean_after_drop_m", Num(Mean(after_drop))},
                                         {"steady_state_samples_after_drop", after_drop.size()}};
      }
      others[v.name] = {{"dropped_from_cost_s", Num(dropped)}, {"formation_error", errs}};
      fault_lines->push_back(fmt::format(
          "fault kill_controller: {} {}", v.name,
          std::isfinite(dropped) ? fmt::format("dropped {} from its cost at t = {:.2f} s",
                                               sc.vehicles[k].name, dropped)
                                 : fmt::format("kept {} in its cost", sc.vehicles[k].name)));
    }
    j["followers"] = others;
    fj["kill_controller"] = j;
    fault_lines->insert(
        fault_lines->begin(),
        fmt::format(
            "fault kill_controller: {} at t = {:.2f} s; autopilot failsafe {}; "
            "touchdown {} ; motors {} ; landed safely {}",
            sc.vehicles[k].name, faults.kill_controller.time,
            ap.failsafe ? fmt::format("at t = {:.2f} s", ap.failsafe_time) : "never",
            std::isfinite(r.downed[k].impact_time)
                ? fmt::format("at t = {:.2f} s, v_z {:.2f} m/s, at ({:.2f}, {:.2f}) m",
                              r.downed[k].impact_time, r.downed[k].impact_vz,
                              r.downed[k].impact_position.x(), r.downed[k].impact_position.y())
                : std::string("none"),
            ap.disarmed_by_failsafe ? fmt::format("off at t = {:.2f} s", ap.disarm_time)
                                    : std::string("not stopped by the autopilot"),
            safe));
  }
  if (faults.motors_off.active()) {
    const int k = faults.motors_off.index;
    downed_by.push_back(k);
    fj["motors_off"] = {{"vehicle", sc.vehicles[k].name},
                        {"time_s", faults.motors_off.time},
                        {"impact_time_s", Num(r.downed[k].impact_time)},
                        {"impact_vertical_speed_mps", Num(r.downed[k].impact_vz)},
                        {"impact_position_m", vec2(r.downed[k].impact_position)}};
    fault_lines->push_back(fmt::format(
        "fault motors_off: {} at t = {:.2f} s; {}", sc.vehicles[k].name, faults.motors_off.time,
        std::isfinite(r.downed[k].impact_time)
            ? fmt::format(
                  "hit the ground at t = {:.2f} s with v_z {:.2f} m/s at ({:.2f}, {:.2f}) m",
                  r.downed[k].impact_time, r.downed[k].impact_vz, r.downed[k].impact_position.x(),
                  r.downed[k].impact_position.y())
            : std::string("did not reach the ground")));
  }
  if (!faults.sensor_dropouts.empty()) {
    json arr = json::array();
    for (std::size_t w = 0; w < faults.sensor_dropouts.size(); ++w) {
      const auto& d = faults.sensor_dropouts[w];
      arr.push_back({{"vehicle", d.vehicle},
                     {"sensor", std::string(ToString(d.sensor))},
                     {"from_s", d.from},
                     {"to_s", d.to},
                     {"dropped", r.dropped[w]}});
      fault_lines->push_back(
          fmt::format("fault sensor_dropout: {} {} from {:.2f} to {:.2f} s: {} "
                      "measurements dropped",
                      d.vehicle, ToString(d.sensor), d.from, d.to, r.dropped[w]));
    }
    fj["sensor_dropouts"] = arr;
  }
  if (faults.outlier_rate > 0.0) {
    fj["outliers"] = {{"rate", faults.outlier_rate},
                      {"size", faults.outlier_size},
                      {"measurements", r.measurements},
                      {"corrupted", r.outliers}};
    fault_lines->push_back(fmt::format("fault outliers: {} of {} measurements given an error of {}",
                                       r.outliers, r.measurements, faults.outlier_size));
  }
  if (faults.solver_failure_rate > 0.0) {
    fj["solver_failures"] = {{"rate", faults.solver_failure_rate},
                             {"injected", r.injected_failures},
                             {"nmpc_steps", nmpc_steps},
                             {"recoveries", recoveries},
                             {"failsafes", failsafes}};
    fault_lines->push_back(fmt::format(
        "fault solver_failures: {} of {} NMPC steps forced to fall back; {} re-initialisations, "
        "{} failsafes",
        r.injected_failures, nmpc_steps, recoveries, failsafes));
  }
  if (faults.any()) {
    bool others_safe = true;
    json names = json::array();
    for (int k : downed_by) names.push_back(sc.vehicles[k].name);
    for (int i = 0; i < nv; ++i) {
      if (std::find(downed_by.begin(), downed_by.end(), i) != downed_by.end()) continue;
      if (!r.controlled[i]) continue;  // moved by hand
      others_safe = others_safe && vehicles[sc.vehicles[i].name].value("landed_safely", false);
    }
    fj["downed_vehicles"] = names;
    fj["landed_safely_except_downed"] = others_safe;
  }

  // ---- Failures: why this run must not count as a success, per vehicle.
  const bool complete = r.stopped.empty() && r.sim_error.empty();
  json run_failures = json::array();
  long collisions = 0, ground_strikes = 0, hard_touchdowns = 0;
  // Collisions: every pair whose true CoMs came closer than metrics.collision_distance, also
  // with a vehicle downed by a fault or moved by hand (they are in the air all the same).
  for (int i = 0; i < nv; ++i) {
    for (int k = i + 1; k < nv; ++k) {
      const PairApproach& p = r.pairs[PairIndex(i, k, nv)];
      if (std::isnan(p.first_collision_time)) continue;
      ++collisions;
      run_failures.push_back(
          {{"vehicle", sc.vehicles[i].name},
           {"vehicles", {sc.vehicles[i].name, sc.vehicles[k].name}},
           {"kind", "collision"},
           {"time_s", p.first_collision_time},
           {"reason", fmt::format("collision with {} at t = {:.2f} s: true CoM distance below {} m "
                                  "(metrics.collision_distance), closest {:.3f} m at t = {:.2f} s",
                                  sc.vehicles[k].name, p.first_collision_time,
                                  sc.metrics.collision_distance, p.min_distance, p.min_time)}});
    }
  }
  for (int i = 0; i < nv; ++i) {
    const auto& v = sc.vehicles[i];
    const VehicleRecord& L = r.vehicles[i];
    auto fail = [&](const char* kind, double time, const std::string& reason) {
      run_failures.push_back(
          {{"vehicle", v.name}, {"kind", kind}, {"time_s", Num(time)}, {"reason", reason}});
    };
    if (std::isfinite(L.envelope_time)) fail("envelope", L.envelope_time, L.envelope_reason);
    const bool downed_by_fault =
        std::find(downed_by.begin(), downed_by.end(), i) != downed_by.end();
    if (!r.controlled[i] || downed_by_fault) continue;  // moved by hand, or downed on purpose
    const double takeoff_height =
        std::isfinite(v.takeoff_height) ? v.takeoff_height : sc.takeoff_height;
    if (complete && !(L.max_altitude >= 0.5 * takeoff_height)) {
      fail("never_took_off", kNaN,
           fmt::format("never took off: highest altitude {:.3f} m, take-off height {:.2f} m",
                       L.max_altitude, takeoff_height));
    }
    if (std::isfinite(L.failsafe_time)) {
      fail("failsafe", L.failsafe_time,
           fmt::format("failsafe at t = {:.2f} s ({})", L.failsafe_time, L.failsafe_reason));
    }
    if (std::isfinite(L.ground_strike_time)) {
      ++ground_strikes;
      fail("ground_strike", L.ground_strike_time,
           fmt::format("struck the ground at t = {:.2f} s in the {} phase: true CoM within {} m "
                       "of its resting height, vertical speed {:.3f} m/s",
                       L.ground_strike_time, L.ground_strike_phase, kGroundContactHeight,
                       L.ground_strike_vz));
    }
    if (std::isfinite(L.touchdown_vz) &&
        !(std::abs(L.touchdown_vz) < sc.metrics.touchdown_speed_max)) {
      ++hard_touchdowns;
      fail("hard_touchdown", L.touchdown_time,
           fmt::format("hard touchdown at t = {:.2f} s: vertical speed {:.3f} m/s (max {} m/s, "
                       "metrics.touchdown_speed_max)",
                       L.touchdown_time, L.touchdown_vz, sc.metrics.touchdown_speed_max));
    }
    const json& vj = vehicles[v.name];
    if (complete && !vj.value("landed_safely", false)) {
      fail("not_landed", kNaN,
           fmt::format(
               "not landed safely at the end: touchdown vertical speed {} (max {} m/s), motors off "
               "{}, final tilt {:.3f} rad (max {})",
               vj["touchdown_vertical_speed_mps"].is_number()
                   ? fmt::format("{:.3f} m/s", vj["touchdown_vertical_speed_mps"].get<double>())
                   : std::string("none (no touchdown)"),
               sc.metrics.touchdown_speed_max, vj.value("motors_off_at_end", false),
               vj.value("final_tilt_rad", kNaN), sc.metrics.max_tilt_landed));
    }
  }

  json s;
  s["scenario"] = sc.name;
  s["complete"] = complete;
  if (!r.stopped.empty()) s["stopped"] = r.stopped;
  if (!r.sim_error.empty()) s["error"] = r.sim_error;
  s["failures"] = run_failures;
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
  s["steady_state_formation_error_m"] = Num(steady_worst);
  s["mean_formation_error_m"] = Num(mean_worst);
  s["max_formation_error_m"] = Num(max_worst);
  s["mean_formation_error_flight_m"] = Num(flight_mean_worst);
  s["max_formation_error_flight_m"] = Num(flight_max_worst);
  s["solver_time_max_s"] = options.timing ? Num(time_max) : json(nullptr);
  s["solver_time_max_after_first_step_s"] = options.timing ? Num(time_max_first) : json(nullptr);
  s["solver_time_median_s"] = Num(Median(all_times));
  s["solver_steps_over_budget_share"] =
      !options.timing  ? json(nullptr)
      : nmpc_steps > 0 ? json(static_cast<double>(over_budget) / static_cast<double>(nmpc_steps))
                       : json(0.0);
  s["sample_time_s"] = sc.rti.sample_time;
  s["nmpc_steps"] = nmpc_steps;
  s["fallbacks"] = fallbacks;
  s["recoveries"] = recoveries;
  s["failsafes"] = failsafes;
  s["leaderless_landings"] = leaderless_landings;
  s["solver_failures"] = failures;
  s["solver_converged_every_step"] = failures == 0 && fallbacks == 0 && nmpc_steps > 0;
  s["guarded_commands"] = guarded;
  s["min_separation_m"] = Num(r.min_separation);
  s["min_separation_pair"] = r.min_separation_pair[0] >= 0
                                 ? json{sc.vehicles[r.min_separation_pair[0]].name,
                                        sc.vehicles[r.min_separation_pair[1]].name}
                                 : json(nullptr);
  s["min_separation_time_s"] = Num(r.min_separation_time);
  s["collision_distance_m"] = sc.metrics.collision_distance;
  s["collisions"] = collisions;
  s["ground_strikes"] = ground_strikes;
  s["hard_touchdowns"] = hard_touchdowns;
  s["landed_safely"] = landed_safely;
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

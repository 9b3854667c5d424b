// SPDX-License-Identifier: BSD-3-Clause
// The per-record summarisers of summary.json (run_summaries.hpp).
#include "fnmpc/experiment/run_summaries.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "fnmpc/formation/neighbour_thrust.hpp"
#include "fnmpc/onboard/formation_print.hpp"

namespace fnmpc::experiment {

using json = nlohmann::json;

json SummariseVehicles(const config::ScenarioConfig& sc, const RunOptions& options,
                       const RunRecord& r, VehicleTotals* totals) {
  VehicleTotals& T = *totals;
  const bool manual = sc.leader_mode == "manual";
  const int nv = static_cast<int>(sc.vehicles.size());
  json vehicles = json::object();
  const auto worse = [](double a, double b) {
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
      T.steady_worst = worse(T.steady_worst, Mean(L.steady_errors));
      T.mean_worst = worse(T.mean_worst, Mean(L.errors));
      T.max_worst = worse(T.max_worst, Max(L.errors));
      T.flight_mean_worst = worse(T.flight_mean_worst, Mean(L.flight_errors));
      T.flight_max_worst = worse(T.flight_max_worst, Max(L.flight_errors));
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
      T.recoveries += L.reinitialisations;
      T.failsafes += std::isfinite(L.failsafe_time) ? 1 : 0;
      T.leaderless_landings += std::isfinite(L.tie_loss_time) ? 1 : 0;
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
      T.landed_safely = T.landed_safely && ok;
      T.all_times.insert(T.all_times.end(), L.solver_time.begin(), L.solver_time.end());
      T.time_max = worse(T.time_max, Max(L.solver_time));
      if (L.solver_time.size() > 1) {
        T.time_max_first = worse(T.time_max_first,
                                 *std::max_element(L.solver_time.begin() + 1, L.solver_time.end()));
      }
      T.fallbacks += L.fallbacks;
      T.failures += L.failures;
      T.over_budget += L.over_budget;
      T.nmpc_steps += L.steps;
      T.guarded += L.guarded;
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
  return vehicles;
}

json SummariseFaults(const config::ScenarioConfig& sc, const RunRecord& r, const json& vehicles,
                     const VehicleTotals& T, std::vector<int>* downed_by,
                     std::vector<std::string>* fault_lines) {
  const int nv = static_cast<int>(sc.vehicles.size());
  const config::ScenarioFaults& faults = sc.faults;
  json fj = json::object();
  auto vec2 = [](const Vec3& p) { return p.allFinite() ? json{p.x(), p.y()} : json(nullptr); };
  if (faults.kill_controller.active()) {
    const int k = faults.kill_controller.index;
    downed_by->push_back(k);
    const sim::AutopilotStatus& ap = r.final_autopilot[k];
    const bool safe = vehicles.at(sc.vehicles[k].name).value("landed_safely", false);
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
    downed_by->push_back(k);
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
                             {"nmpc_steps", T.nmpc_steps},
                             {"recoveries", T.recoveries},
                             {"failsafes", T.failsafes}};
    fault_lines->push_back(fmt::format(
        "fault solver_failures: {} of {} NMPC steps forced to fall back; {} re-initialisations, "
        "{} failsafes",
        r.injected_failures, T.nmpc_steps, T.recoveries, T.failsafes));
  }
  if (faults.any()) {
    bool others_safe = true;
    json names = json::array();
    for (int k : *downed_by) names.push_back(sc.vehicles[k].name);
    for (int i = 0; i < nv; ++i) {
      if (std::find(downed_by->begin(), downed_by->end(), i) != downed_by->end()) continue;
      if (!r.controlled[i]) continue;  // moved by hand
      others_safe = others_safe && vehicles.at(sc.vehicles[i].name).value("landed_safely", false);
    }
    fj["downed_vehicles"] = names;
    fj["landed_safely_except_downed"] = others_safe;
  }
  return fj;
}

json SummariseFailures(const config::ScenarioConfig& sc, const RunRecord& r, const json& vehicles,
                       const std::vector<int>& downed_by, bool complete, FailureCounts* counts) {
  FailureCounts& C = *counts;
  const int nv = static_cast<int>(sc.vehicles.size());
  json run_failures = json::array();
  // Collisions: every pair whose true CoMs came closer than metrics.collision_distance, also
  // with a vehicle downed by a fault or moved by hand (they are in the air all the same).
  for (int i = 0; i < nv; ++i) {
    for (int k = i + 1; k < nv; ++k) {
      const PairApproach& p = r.pairs[PairIndex(i, k, nv)];
      if (std::isnan(p.first_collision_time)) continue;
      ++C.collisions;
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
      ++C.ground_strikes;
      fail("ground_strike", L.ground_strike_time,
           fmt::format("struck the ground at t = {:.2f} s in the {} phase: true CoM within {} m "
                       "of its resting height, vertical speed {:.3f} m/s",
                       L.ground_strike_time, L.ground_strike_phase, kGroundContactHeight,
                       L.ground_strike_vz));
    }
    if (std::isfinite(L.touchdown_vz) &&
        !(std::abs(L.touchdown_vz) < sc.metrics.touchdown_speed_max)) {
      ++C.hard_touchdowns;
      fail("hard_touchdown", L.touchdown_time,
           fmt::format("hard touchdown at t = {:.2f} s: vertical speed {:.3f} m/s (max {} m/s, "
                       "metrics.touchdown_speed_max)",
                       L.touchdown_time, L.touchdown_vz, sc.metrics.touchdown_speed_max));
    }
    const json& vj = vehicles.at(v.name);
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
  return run_failures;
}

}  // namespace fnmpc::experiment

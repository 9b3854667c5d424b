// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/run_observers.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string_view>

#include "fnmpc/config/output_files.hpp"
#include "fnmpc/onboard/controller_setup.hpp"

namespace fnmpc::experiment {

using formation::FlightPhase;

void ImpactObserver::PhysicsStep(const ClosedLoop& loop, double t) {
  const int nv = loop.vehicles();
  if (prev_vz_.empty()) prev_vz_.assign(static_cast<std::size_t>(nv), 0.0);
  for (int i = 0; i < nv; ++i) {
    DownedLog& downed = rec_->downed[i];
    if (!(loop.killed(i) || loop.world().MotorsOffByFault(i)) || !std::isnan(downed.impact_time)) {
      continue;
    }
    // Contact: the CoM within 1.5 cm of its resting height, or a hard or tilted impact that
    // the contact stops higher (CoM below 0.3 m above rest, about a tilted foot's reach, and
    // an upward jump of the vertical speed of more than 0.02 m/s in one 1 ms step: > 2 g of
    // contact deceleration). The speed is the one just before the contact.
    const sim::TrueState x = loop.world().world().GetTrueState(i);
    const double z = x.position.z() - sim::World::kRestHeight;
    const bool jump = x.velocity.z() - prev_vz_[i] > 0.02;
    if (z < 0.015 || (z < 0.3 && jump)) {
      downed.impact_time = t;
      downed.impact_vz = std::min(prev_vz_[i], x.velocity.z());
      downed.impact_position = x.position;
    }
    prev_vz_[i] = x.velocity.z();
  }
}

void SeparationObserver::ControlStepBegin(const ClosedLoop& loop, const ControlStep& step) {
  const int nv = loop.vehicles();
  const std::vector<sim::TrueState>& truth = loop.truth();
  const double t = step.t;
  RunRecord& rec = *rec_;
  for (int i = 0; i < nv; ++i) {
    for (int j = i + 1; j < nv; ++j) {
      const double d = (truth[i].position - truth[j].position).norm();
      PairApproach& pair = rec.pairs[PairIndex(i, j, nv)];
      if (d < pair.min_distance) {
        pair.min_distance = d;
        pair.min_time = t;
      }
      if (d < loop.scenario().metrics.collision_distance && std::isnan(pair.first_collision_time)) {
        pair.first_collision_time = t;
      }
      for (const auto& [a, b] : {std::pair{i, j}, std::pair{j, i}}) {
        VehicleRecord& A = rec.vehicles[static_cast<std::size_t>(a)];
        if (d < A.min_separation) {
          A.min_separation = d;
          A.min_separation_time = t;
          A.min_separation_to = b;
        }
      }
      if (d < rec.min_separation) {
        rec.min_separation = d;
        rec.min_separation_time = t;
        rec.min_separation_pair[0] = i;
        rec.min_separation_pair[1] = j;
      }
    }
  }
}

void FlightRecordObserver::CommandsSent(const ClosedLoop& loop, const ControlStep& step) {
  const config::ScenarioConfig& sc = loop.scenario();
  const int nv = loop.vehicles();
  const double t = step.t;
  if (prev_.empty()) prev_.resize(static_cast<std::size_t>(nv));
  for (int i = 0; i < nv; ++i) {
    const std::string& name = sc.vehicles[i].name;
    VehicleRecord& L = rec_->vehicles[i];
    const DownedLog& downed = rec_->downed[i];
    const sim::TrueState& x = loop.truth()[i];
    const formation::VehicleController* ctrl = loop.controller(i);
    if (loop.killed(i)) {
      if (std::isnan(L.touchdown_time) && std::isfinite(downed.impact_time)) {
        L.touchdown_time = downed.impact_time;
        L.touchdown_vz = downed.impact_vz;
      }
      L.motors_off = x.rotor_rpm.norm() < 1.0;
      continue;
    }
    if (ctrl == nullptr) continue;
    const formation::ControlOutput& out = loop.output(i);
    if (out.recovery == formation::RecoveryAction::kReinitialise) ++L.reinitialisations;
    if (out.recovery == formation::RecoveryAction::kShiftLandingSite) ++L.landing_site_shifts;
    if (out.recovery == formation::RecoveryAction::kLand) {
      L.tie_loss_time = t;
      L.tie_loss_reason = std::string(formation::ToString(out.recovery_reason));
      loop.Event(t, name + " lands, no formation tie to the leader (" + L.tie_loss_reason + ")");
    }
    if (out.recovery == formation::RecoveryAction::kFailsafe) {
      L.failsafe_time = t;
      L.failsafe_reason = std::string(formation::ToString(out.recovery_reason));
      loop.Event(t, name + " hands over to the failsafe (" + L.failsafe_reason + ")");
    }
    if (out.nmpc) {
      if (formation::InjectedSolverFailure(ctrl->config().safety, i, t, sc.rti.sample_time))
        ++rec_->injected_failures;
      ++L.steps;
      if (L.steps == 1) {
        L.first_step_time = out.solver_time;
        L.max_thrust_jump_at_switch = std::abs(out.thrust - prev_[i].thrust);
      }
      if (loop.options().timing) L.solver_time.push_back(out.solver_time);
      if (out.solver_time > sc.rti.sample_time) ++L.over_budget;
      if (out.fallback) ++L.fallbacks;
      if (out.status != rti::RtiStatus::kSuccess) ++L.failures;
      L.kkt.push_back(out.kkt);
      L.cost.push_back(out.cost);
    }
    if (out.guarded) ++L.guarded;
    if (out.attitude_offset_bounded) ++L.attitude_offset_bounded;
    if (out.nmpc && out.attitude_offset.allFinite()) L.attitude_offset = out.attitude_offset;
    if (out.neighbour_thrust_bounded > 0) {
      L.neighbour_thrust_bounded[static_cast<std::size_t>(out.neighbour_thrust_bound)] +=
          out.neighbour_thrust_bounded;
    }
    // Touchdown: the first control step of the landing phase with the true CoM within
    // 1.5 cm of its resting height (the feet touch); its true vertical speed is kept.
    const bool on_ground = x.position.z() < sim::World::kRestHeight + kGroundContactHeight;
    if ((out.phase == FlightPhase::kLanding || out.phase == FlightPhase::kLanded ||
         out.phase == FlightPhase::kFailsafe) &&
        std::isnan(L.touchdown_time) && on_ground) {
      L.touchdown_vz = x.velocity.z();
      L.touchdown_time = t;
    }
    // Ground strike: the same contact while the vehicle is meant to fly (NMPC phase, or a
    // take-off that had lifted off). Vehicles a fault downs are judged apart.
    const bool motors_off_by_fault = loop.world().MotorsOffByFault(i);
    const bool flying = out.phase == FlightPhase::kNmpc ||
                        (out.phase == FlightPhase::kTakeoff && L.max_altitude >= kLiftOffHeight);
    if (flying && on_ground && !motors_off_by_fault && std::isnan(L.ground_strike_time)) {
      L.ground_strike_time = t;
      L.ground_strike_vz = std::min(L.previous_vz, x.velocity.z());
      L.ground_strike_phase = std::string(formation::ToString(out.phase));
      loop.Event(t, name + " struck the ground (" + L.ground_strike_phase + " phase)");
    }
    L.previous_vz = x.velocity.z();
    if (out.phase == FlightPhase::kLanded) L.motors_off = true;
    // Motors off (fault): its touchdown is the impact, not what its controller sees after
    // the crash.
    if (sc.faults.motors_off.index == i && std::isfinite(downed.impact_time)) {
      L.touchdown_time = downed.impact_time;
      L.touchdown_vz = downed.impact_vz;
    }
    prev_[i] = out;
  }
}

void EnvelopeObserver::VehicleStep(const ClosedLoop& loop, const ControlStep& step, int i) {
  const config::ScenarioConfig& sc = loop.scenario();
  VehicleRecord& L = rec_->vehicles[i];
  const sim::TrueState& x = loop.truth()[i];
  const double altitude = x.position.z() - sim::World::kRestHeight;
  const Vec3 start = loop.world_config().vehicles[static_cast<std::size_t>(i)].position;
  const double distance = (x.position - start).head<2>().norm();
  L.max_altitude = std::max(L.max_altitude, altitude);
  L.max_distance = std::max(L.max_distance, distance);
  if (std::isnan(L.envelope_time) &&
      (!(altitude <= sc.envelope.max_altitude) || !(distance <= sc.envelope.max_distance))) {
    L.envelope_time = step.t;
    L.envelope_reason = fmt::format(
        "left the flight envelope at t = {:.2f} s: altitude {:.2f} m (max_altitude {:.2f}), "
        "{:.2f} m from its start (max_distance {:.2f}), at ({:.2f}, {:.2f}, {:.2f}) m",
        step.t, altitude, sc.envelope.max_altitude, distance, sc.envelope.max_distance,
        x.position.x(), x.position.y(), x.position.z());
  }
}

void FormationErrorObserver::VehicleStep(const ClosedLoop& loop, const ControlStep& step, int i) {
  const config::ScenarioConfig& sc = loop.scenario();
  const auto& v = sc.vehicles[i];
  VehicleRecord& L = rec_->vehicles[i];
  FormationErrorSample& s = current_[static_cast<std::size_t>(i)];
  const double t = step.t;
  const bool window = t >= sc.trajectory_start && t < config::LandingTime(sc, i);
  s.steady = window && step.settled;
  const sim::TrueState& x = loop.truth()[i];
  const formation::VehicleController* ctrl = loop.controller(i);
  s.relative.fill(Vec3::Constant(kNaN));
  s.estimated_relative.fill(Vec3::Constant(kNaN));
  s.errors.fill(kNaN);
  s.formation_error = kNaN;
  if (!v.leader) {
    s.formation_error =
        onboard::FormationError(sc, i, loop.positions(), x.euler.z(), &s.errors, &s.relative);
    for (std::size_t j = 0; j < v.neighbours.size(); ++j) {
      if (ctrl && j < ctrl->estimates().neighbours.size()) {
        s.estimated_relative[j] = ctrl->estimates().neighbours[j].head<3>();
      }
      if (window) L.nb_errors[j].push_back(s.errors[j]);
      if (s.steady) L.nb_steady[j].push_back(s.errors[j]);
    }
    if (window) L.errors.push_back(s.formation_error);
    if (t >= sc.takeoff_time && std::isnan(L.touchdown_time)) {
      L.flight_errors.push_back(s.formation_error);
    }
    if (s.steady) L.steady_errors.push_back(s.formation_error);
    if (window) {
      L.samples.push_back({t, s.steady, s.errors, loop.output(i).active_neighbours});
    }
  }
  s.tracking = kNaN;
  if (v.leader && step.leader_ref.allFinite()) {
    s.tracking = (x.position - step.leader_ref).norm();
    if (window && !loop.manual_leader()) L.tracking.push_back(s.tracking);
  }
}

CsvLogObserver::CsvLogObserver(const config::ScenarioConfig& scenario, const std::string& dir,
                               const FormationErrorObserver* errors)
    : errors_(errors) {
  csv_.reserve(scenario.vehicles.size());
  for (const auto& v : scenario.vehicles) {
    csv_.emplace_back(config::PathInside(dir, v.name + ".csv"));
  }
}

void CsvLogObserver::VehicleStep(const ClosedLoop& loop, const ControlStep& step, int i) {
  const FormationErrorSample& s = errors_->current(i);
  const formation::VehicleController* ctrl = loop.controller(i);
  const formation::ControlOutput& out = loop.output(i);
  const estimation::VehicleEstimate no_estimate{};
  const estimation::VehicleEstimate& e = ctrl ? ctrl->estimates().own : no_estimate;
  VehicleLogRow row;
  row.t = step.t;
  row.phase = loop.killed(i) ? std::string_view("killed") : formation::ToString(out.phase);
  row.truth = &loop.truth()[i];
  row.estimate = &e;
  row.output = &out;
  row.leader_ref = step.leader_ref;
  row.tracking = loop.scenario().vehicles[i].leader ? s.tracking : kNaN;
  row.relative = &s.relative;
  row.estimated_relative = &s.estimated_relative;
  row.errors = &s.errors;
  row.formation_error = s.formation_error;
  row.steady = s.steady;
  row.estimator_rejections = ctrl ? ctrl->estimator_rejections() : 0;
  // m (d + the wake model's part): with compensation wake the estimator's d is the rest.
  if (ctrl) row.estimated_force = ctrl->config().params.mass * (e.disturbance + out.wake);
  csv_[static_cast<std::size_t>(i)].Write(row);
}

void CsvLogObserver::Finish(const ClosedLoop& /*loop*/) {
  for (VehicleCsvLog& log : csv_) log.Finish();
}

void ProgressObserver::ControlStepEnd(const ClosedLoop& loop, const ControlStep& step) {
  if (step.t < next_) return;
  std::fprintf(stderr, "\r%s t = %5.1f / %.1f s", label_.c_str(), step.t, loop.duration());
  std::fflush(stderr);
  next_ += 5.0;
}

void ProgressObserver::Finish(const ClosedLoop& loop) {
  std::fprintf(stderr, "\r%s t = %5.1f / %.1f s\n", label_.c_str(), loop.duration(),
               loop.duration());
}

void ProgressObserver::Event(double t, const std::string& what) const {
  std::fprintf(stderr, "\n%s t = %.2f s: %s\n", label_.c_str(), t, what.c_str());
}

}  // namespace fnmpc::experiment

// SPDX-License-Identifier: BSD-3-Clause
// VehicleController's flight phases: the take-off PID and its switch to the NMPC, the
// NMPC step with its input (neighbours, wakes, obstacles, compensation) and the recovery
// ladder, the landing, the failsafe controller, and the guard on every command.
// Measurement routing, tracking and neighbour presence are in vehicle_controller.cpp.
#include <algorithm>
#include <array>
#include <cmath>

#include "fnmpc/formation/neighbour_acceleration.hpp"
#include "fnmpc/formation/neighbour_thrust.hpp"
#include "fnmpc/formation/nmpc_core.hpp"
#include "fnmpc/formation/throttle_map.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"

namespace fnmpc::formation {

namespace {

/// Failsafe descent without height or vertical speed: a thrust just below hover (about
/// 0.3 m/s^2 down) so that the vehicle sinks slowly instead of holding an unknown height.
constexpr double kFailsafeBlindThrustFactor = 0.97;
/// Lateral shift of a sensed vehicle to the observer's left, as a fraction of r_min
/// (NearestObstacles: the passing rule).
constexpr double kPassingShift = 0.3;
/// Touchdown: the ground-contact condition must hold this long before the motors stop [s]
/// (PX4's multicopter land detector, LAND_DETECTOR_TRIGGER_TIME_US = 300 ms). Without it a
/// descent that starts within touchdown_margin of the ground stopped the motors at once, in
/// the air (fault campaign run 55: a 3 cm drop, 0.67 m/s at impact).
constexpr double kTouchdownConfirmTime = 0.3;
/// Landing: a site moved clear of a vehicle below is put this much beyond r_min from it [m],
/// so that estimate noise (centimetres) does not move it again at every step.
constexpr double kLandingSiteClearance = 0.1;
// A descent that has waited this long [s] above a vehicle moves its site one clearance further.
constexpr double kLandingSiteWait = 2.0;

}  // namespace

// The kObstacleSlots nearest tracked vehicles (formation neighbours and others) with a
// finite estimate and an accepted measurement within neighbour_timeout: the last valid
// estimate is kept while it is that fresh. No allocation (fixed arrays).
void VehicleController::NearestObstacles(double t, NmpcInput* in) const {
  in->obstacles = 0;
  if (!(config_.safety.collision_radius > 0.0)) return;
  const double timeout = config_.safety.neighbour_timeout;
  std::array<double, kObstacleSlots> dist{};
  const double kappa2 = collision_sigmas_ * collision_sigmas_;
  auto offer = [&](const estimation::NeighbourStateVec& x, const estimation::NeighbourStateCov& cov,
                   double seen) {
    if (!x.allFinite() || !std::isfinite(seen) || t - seen > timeout) return;
    const double d = x.head<3>().norm();
    int pos = in->obstacles;
    if (pos == kObstacleSlots) {
      if (d >= dist[kObstacleSlots - 1]) return;
      pos = kObstacleSlots - 1;
    } else {
      ++in->obstacles;
    }
    // Insertion into the slots sorted by distance.
    for (; pos > 0 && dist[pos - 1] > d; --pos) {
      dist[pos] = dist[pos - 1];
      in->obstacle_rel[pos] = in->obstacle_rel[pos - 1];
      in->obstacle_vel[pos] = in->obstacle_vel[pos - 1];
      in->obstacle_normal[pos] = in->obstacle_normal[pos - 1];
      in->obstacle_spread[pos] = in->obstacle_spread[pos - 1];
    }
    dist[pos] = d;
    in->obstacle_rel[pos] = x.head<3>();
    in->obstacle_vel[pos] = x.segment<3>(3);
    // Separating plane through the current geometry, its normal tilted to the observer's
    // left (a right-hand passing rule without communication): two vehicles heading at each
    // other both give way to their right instead of mirroring each other's manoeuvre.
    const Vec3 rel = x.head<3>();
    const double h = rel.head<2>().norm();
    const Vec3 left = h > 1e-6 ? Vec3(-rel.y() / h, rel.x() / h, 0.0) : Vec3::Zero();
    const Vec3 n = rel + kPassingShift * config_.safety.collision_radius * left;
    in->obstacle_normal[pos] = n.norm() > 1e-9 ? Vec3(n.normalized()) : Vec3(0.0, 0.0, 1.0);
    // The chance constraint's margin (ObstacleAt); a non-finite covariance gives none.
    const Vec3& u = in->obstacle_normal[pos];
    const Vec3 spread(u.dot(cov.block<3, 3>(0, 0) * u), u.dot(cov.block<3, 3>(0, 3) * u),
                      u.dot(cov.block<3, 3>(3, 3) * u));
    in->obstacle_spread[pos] = spread.allFinite() ? Vec3(kappa2 * spread) : Vec3(Vec3::Zero());
  };
  for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
    offer(estimates_.neighbours[j], estimates_.neighbour_covariances[j], presence_[j].seen);
  }
  for (std::size_t k = 0; k < tracks_.size(); ++k)
    offer(estimates_.others[k], estimates_.other_covariances[k], tracks_[k].presence.seen);
}

// Take-off and landing PID: an estimate unusable for estimate_timeout (the ladder's timer)
// hands over to the failsafe. Returns true when it did.
bool VehicleController::PidEstimateLost(double t, double z, ControlOutput* out) {
  const auto& own = estimates_.own;
  const bool usable = own.valid && std::isfinite(z) && own.velocity.allFinite() &&
                      own.euler.allFinite() && !VelocityInconsistent(t);
  const RecoveryDecision d = ladder_.Update(t, usable, false);
  if (d.action != RecoveryAction::kFailsafe) return false;
  out->recovery = d.action;
  out->recovery_reason = d.reason;
  EnterFailsafe(t, d.reason);
  return true;
}

void VehicleController::TriggerFailsafe(double t) {
  if (phase_ == FlightPhase::kLanded || phase_ == FlightPhase::kIdle || ladder_.failsafe()) return;
  ladder_.Trigger(RecoveryReason::kCommanded);
  EnterFailsafe(t, RecoveryReason::kCommanded);
}

void VehicleController::EnterFailsafe(double t, RecoveryReason reason) {
  failsafe_reason_ = reason;
  phase_ = FlightPhase::kFailsafe;
  phase_start_ = t;
  contact_.Reset();
  const double z = FailsafeHeight(t);
  z_ref_ = std::isfinite(z) ? z : kNaN;
  pid_.Reset(std::isfinite(last_command_[0]) ? last_command_[0] : config_.params.mass * kGravity);
  blend_from_ = Vec3::Constant(kNaN);  // the failsafe acts at once
}

// The failsafe's height: the raw motion-capture height when fresh, else the controller's
// height if the estimate is still valid.
double VehicleController::FailsafeHeight(double t) const {
  if (RawMocapFresh(t)) return raw_z_;
  return estimates_.own.valid && !VelocityInconsistent(t) ? Height(t) : kNaN;
}

// Touchdown: on the ground (height within the margin) and no longer moving down, so the
// motors never stop while the vehicle still falls, for kTouchdownConfirmTime without a
// break: a vehicle hovering a few centimetres up when its reference passes the ground is
// still flying, and the PID brings it down within that time.
bool VehicleController::TouchedDown(double t, double z, double vz) {
  const double ground = config_.ground_height;
  const bool settled = std::isfinite(vz) && std::abs(vz) < 0.1;
  const bool contact = std::isfinite(z) && z < ground + config_.touchdown_margin &&
                       z_ref_ < ground && (settled || z_ref_ <= ground - 0.3);
  contact_.Update(contact, t);
  return contact_.For(t, kTouchdownConfirmTime - 1e-9);
}

// Landing clear of other vehicles: every sensed vehicle (formation neighbour or other, finite
// estimate, an accepted measurement within neighbour_timeout, as for collision avoidance)
// that is not clearly above (its CoM less than r_min higher) and within r_min of the landing
// site horizontally moves the site away from it, to r_min + kLandingSiteClearance (along the
// line from it through the site, else through the own position, else +x). The PID flies
// there; the descent waits while the vehicle itself is within r_min of one of them
// horizontally and less than 2 r_min above it (higher up it descends while it moves: the
// landing from the take-off height fits its time). A vehicle can hold off its site (the PID's
// offset under an attitude bias, until its slow integral removes it: 0.37 m from a grounded
// vehicle with the site at 0.55 m, waiting past the end of the run), so after kLandingSiteWait
// of waiting the site moves kLandingSiteClearance further from the vehicle it waits for, and
// again after each further kLandingSiteWait. Returns true while the descent waits; a move is
// logged in `out`.
bool VehicleController::ClearLandingSite(double t, ControlOutput* out) {
  const double r = config_.safety.collision_radius;
  const Vec3& p = estimates_.own.position;
  if (!(r > 0.0) || !hold_xy_.allFinite() || !p.head<2>().allFinite()) return false;
  const double timeout = config_.safety.neighbour_timeout;
  bool wait = false;
  auto shift = [&](const Vec<2>& site) {
    hold_xy_ = site;
    ++landing_site_shifts_;
    if (out->recovery == RecoveryAction::kNone) {  // a kLand of the same step is kept
      out->recovery = RecoveryAction::kShiftLandingSite;
      out->recovery_reason = RecoveryReason::kVehicleBelow;
    }
  };
  auto check = [&](const estimation::NeighbourStateVec& x, double seen) {
    if (!x.head<3>().allFinite() || !std::isfinite(seen) || t - seen > timeout) return;
    if (x[2] >= r) return;  // clearly above: not in the descent's way
    const Vec<2> o = p.head<2>() + x.head<2>();
    Vec<2> away = hold_xy_ - o;
    if (away.norm() < r) {
      if (away.norm() < 1e-3) away = -x.head<2>();
      if (away.norm() < 1e-3) away = Vec<2>(1.0, 0.0);
      shift(o + (r + kLandingSiteClearance) * away.normalized());
    }
    if (x.head<2>().norm() < r && -x[2] < 2.0 * r) {
      wait = true;
      if (!std::isfinite(site_wait_start_)) site_wait_start_ = t;
      if (t - site_wait_start_ >= kLandingSiteWait && x.head<2>().norm() > 1e-3) {
        shift(hold_xy_ - kLandingSiteClearance * x.head<2>().normalized());
        site_wait_start_ = t;
      }
    }
  };
  // Two passes: a move away from one vehicle may bring the site near another.
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j)
      check(estimates_.neighbours[j], presence_[j].seen);
    for (std::size_t k = 0; k < tracks_.size(); ++k)
      check(estimates_.others[k], tracks_[k].presence.seen);
  }
  if (!wait) site_wait_start_ = kNaN;
  return wait;
}

// PID landing from here: the height held from where it is, the position from the own
// estimate, the command blended from the last one.
void VehicleController::BeginLanding(double t, double z) {
  phase_ = FlightPhase::kLanding;
  phase_start_ = t;
  contact_.Reset();
  z_ref_ = std::isfinite(z) ? z : config_.takeoff_height;
  hold_xy_ = estimates_.own.position.head<2>();
  site_wait_start_ = kNaN;
  // From the recent mean thrust, not the last command: the PID's integral is the thrust
  // that holds the vehicle, and the landing may start close to the ground.
  const double thrust = std::isfinite(mean_thrust_) ? mean_thrust_ : last_command_[0];
  pid_.Reset(thrust);
  blend_from_ = Vec3(thrust, last_command_[1], last_command_[2]);
  blend_start_ = t;
}

ControlOutput VehicleController::Step(double t) {
  const double dt =
      std::isfinite(last_time_) ? std::max(0.0, t - last_time_) : config_.rti.sample_time;
  last_time_ = t;
  plan_time_ = kNaN;  // set again when this step runs the NMPC (MakePlan)
  ControlOutput out;
  out.time = t;
  out.voltage = voltage_;
  const estimation::VehicleEstimate& own = estimates_.own;
  if (!std::isfinite(yaw_ref_) && own.valid && std::isfinite(own.euler.z()))
    yaw_ref_ = own.euler.z();
  out.yaw = std::isfinite(yaw_ref_) ? yaw_ref_ : 0.0;
  for (const Presence& p : presence_) out.active_neighbours += p.active ? 1 : 0;

  const double z = Height(t);
  UpdatePhase(t, z, &out);
  // (thrust, roll, pitch); a phase may hand over to another within the step (take-off to
  // NMPC, NMPC or PID to failsafe), whose command then replaces it.
  Vec3 command = Vec3::Constant(kNaN);
  switch (phase_) {
    case FlightPhase::kIdle:
    case FlightPhase::kLanded:
      command.setZero();
      break;
    case FlightPhase::kTakeoff:
      command = TakeoffCommand(t, dt, z, &out);
      break;
    case FlightPhase::kLanding:
      command = LandingCommand(t, dt, z, &out);
      break;
    case FlightPhase::kNmpc:
    case FlightPhase::kFailsafe:
      break;  // below
  }
  if (phase_ == FlightPhase::kNmpc) command = NmpcCommand(t, z, &out);
  if (phase_ == FlightPhase::kFailsafe) command = FailsafeCommand(t, dt);
  SendCommand(command, dt, &out);
  return out;
}

// Phase transitions that do not belong to one phase's command law.
void VehicleController::UpdatePhase(double t, double z, ControlOutput* out) {
  const estimation::VehicleEstimate& own = estimates_.own;
  if (phase_ == FlightPhase::kIdle && t >= config_.takeoff_time && own.valid && std::isfinite(z) &&
      std::isfinite(yaw_ref_)) {
    phase_ = FlightPhase::kTakeoff;
    phase_start_ = t;
    z_ref_ = z;
    hold_xy_ = own.position.head<2>();
    height_error_lp_ = kNaN;
    pid_.Reset(config_.params.mass * kGravity);
  }
  // The mission's landing time ends the flight in either airborne phase: a vehicle still in
  // its take-off then (waiting for a neighbour, TakeoffCommand) lands instead of hovering on.
  if ((phase_ == FlightPhase::kNmpc || phase_ == FlightPhase::kTakeoff) &&
      t >= config_.landing_time) {
    BeginLanding(t, z);
  }
  // A follower without a formation tie to the leader lands where it is (docs/safety.md).
  if (phase_ == FlightPhase::kNmpc && !config_.leader) {
    const RecoveryReason lost = TieLossNow();
    if (lost != RecoveryReason::kNone) {
      tie_loss_ = lost;
      BeginLanding(t, z);
      out->recovery = RecoveryAction::kLand;
      out->recovery_reason = lost;
    }
  }
}

// Take-off PID up to the take-off height, then the switch to the NMPC (whose command
// replaces this one in the same step). NaN when it handed over to the failsafe.
Vec3 VehicleController::TakeoffCommand(double t, double dt, double z, ControlOutput* out) {
  const estimation::VehicleEstimate& own = estimates_.own;
  const double h = config_.takeoff_height;
  if (PidEstimateLost(t, z, out)) return Vec3::Constant(kNaN);
  double vz_ref = 0.0;
  if (z_ref_ < h) {
    z_ref_ = std::min(h, z_ref_ + config_.climb_speed * dt);
    vz_ref = z_ref_ < h ? config_.climb_speed : 0.0;
  }
  const PidCommand c = pid_.Update(dt, z_ref_, vz_ref, z, own.velocity, own.euler, HoldError());
  Vec3 command(c.thrust, c.roll, c.pitch);  // also this step's when it lands (below)
  // At height: the height error low-passed over a third of the hover time within
  // kAtHeightTolerance and every sample within kAtHeightBand, for hover_before_switch. The
  // filter lets a gusty push average out (another vehicle's turbulent wake); requiring
  // every sample within the tolerance held a follower under its leader in the take-off
  // for 5-43 s (docs/results.md "Faults and safety"). A steady offset still blocks.
  if (z_ref_ >= h && std::isfinite(z)) {
    const double tau = std::max(config_.hover_before_switch / 3.0, dt);
    const double e = z - h;
    height_error_lp_ = std::isfinite(height_error_lp_)
                           ? height_error_lp_ + (e - height_error_lp_) * std::min(1.0, dt / tau)
                           : e;
  }
  at_height_.Update(z_ref_ >= h && std::abs(z - h) < kAtHeightBand &&
                        std::abs(height_error_lp_) < kAtHeightTolerance,
                    t);
  // The NMPC starts once every neighbour has an estimate, or, neighbour_timeout later,
  // with those that have one: the others start out of the cost and join when first seen
  // (UpdateNeighbourPresence). One never seen (out of sensor range, say) held a follower
  // in its take-off hover until the battery ran out. With none seen by then there is no
  // formation to keep: it lands where it is (as on losing every tie, docs/safety.md).
  const auto seen =
      std::count_if(estimates_.neighbours.begin(), estimates_.neighbours.end(),
                    [](const estimation::NeighbourStateVec& x) { return x.allFinite(); });
  const bool all_seen = seen == static_cast<std::ptrdiff_t>(estimates_.neighbours.size());
  const bool waited =
      at_height_.For(t, config_.hover_before_switch + config_.safety.neighbour_timeout);
  if (waited && seen == 0 && !config_.leader) {
    BeginLanding(t, z);
    out->recovery = RecoveryAction::kLand;
    out->recovery_reason = RecoveryReason::kNoNeighbourSeen;
    return command;
  }
  if (at_height_.For(t, config_.hover_before_switch) && (all_seen || waited) &&
      last_command_.allFinite()) {
    // Smooth switch: the NMPC starts from the PID's last command (guess and blend).
    phase_ = FlightPhase::kNmpc;
    phase_start_ = t;
    nmpc_start_ = t;
    blend_from_ = last_command_;
    blend_start_ = t;
    if (config_.leader) anchor_ = Vec3(own.position.x(), own.position.y(), h);
    nmpc_->Engage(anchor_, yaw_ref_);
    attitude_offset_.Reset();
    applied_offset_.setZero();
    nmpc_->ShiftAttitudeBounds(applied_offset_);
    reinit_pending_ = true;  // the first step iterates to convergence
  }
  return command;
}

// Landing PID: down at descent_speed to below the ground, clear of vehicles below.
Vec3 VehicleController::LandingCommand(double t, double dt, double z, ControlOutput* out) {
  const estimation::VehicleEstimate& own = estimates_.own;
  if (PidEstimateLost(t, z, out)) return Vec3::Constant(kNaN);
  // Not onto another vehicle: move the site clear, descend once not right above it.
  const bool wait = ClearLandingSite(t, out);
  const double vz_ref = wait ? 0.0 : -config_.descent_speed;
  if (!wait) z_ref_ = std::max(config_.ground_height - 0.3, z_ref_ - config_.descent_speed * dt);
  const PidCommand c = pid_.Update(dt, z_ref_, vz_ref, z, own.velocity, own.euler, HoldError());
  double thrust = c.thrust, roll = c.roll, pitch = c.pitch;
  Blend(t, &thrust, &roll, &pitch);
  if (TouchedDown(t, z, own.velocity.z())) {
    phase_ = FlightPhase::kLanded;
    phase_start_ = t;
    return Vec3::Zero();
  }
  return Vec3(thrust, roll, pitch);
}

// The NMPC's input from the estimates: own state, neighbours (with their wakes and
// accelerations where the compensation asks), the last command, the attitude offset, the
// disturbance, the plans and the obstacles.
void VehicleController::FillNmpcInput(double t, double z, NmpcInput* in, ControlOutput* out) {
  const estimation::VehicleEstimate& own = estimates_.own;
  in->t = t;
  in->position = own.position;
  in->own << own.velocity, own.euler;
  in->height = z;
  // Compensation::kWake: the neighbours' thrusts from their estimated accelerations.
  const bool wake_thrust = config_.compensation >= Compensation::kWake && !config_.leader;
  for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
    const auto& x = estimates_.neighbours[j];
    in->active[j] = presence_[j].active && x.allFinite();
    in->neighbours[j] = {x.segment<3>(0), x.segment<3>(3), x[6], x[7], Vec3::Zero(), kNaN};
    if (config_.neighbour_acceleration_decay > 0.0 || wake_thrust) {
      const Vec3 acc = MixedAcceleration(neighbour_ekfs_[j].hover_probability(),
                                         neighbour_acceleration_[j].Update(t, x.segment<3>(3)));
      if (config_.neighbour_acceleration_decay > 0.0) in->neighbours[j].acc = acc;
      if (wake_thrust) {
        // Once per neighbour and step (the horizon holds it): the wake model's thrust.
        const ThrustEstimate T = NeighbourThrust(config_, acc);
        in->neighbours[j].thrust = T.thrust;
        if (T.bound != ThrustBound::kNone) {
          ++out->neighbour_thrust_bounded;
          out->neighbour_thrust_bound = T.bound;
        }
      }
    }
  }
  in->last_command =
      last_command_.allFinite() ? last_command_ : Vec3(config_.params.mass * kGravity, 0.0, 0.0);
  // The NMPC's own input frame: the last reference sent plus the correction it carried.
  in->last_command.tail<2>() += applied_offset_;
  // Offset-free attitude (Compensation::kObserver on, after the blend from the take-off
  // PID): the offset estimate from the attitude measured now and the reference sent last
  // step, and the correction this step's reference carries (AttitudeOffset).
  if (config_.compensation >= Compensation::kObserver && !(t < blend_start_ + config_.blend_time)) {
    attitude_offset_.Observe(t, own.euler.head<2>());
    applied_offset_ = attitude_offset_.reference_offset();
    nmpc_->ShiftAttitudeBounds(applied_offset_);
    out->attitude_offset_bounded = attitude_offset_.bounded();
  }
  out->attitude_offset = attitude_offset_.offset();
  // A non-finite estimate of d never enters the prediction (zero: today's controller).
  if (config_.compensation >= Compensation::kObserver && own.disturbance.allFinite()) {
    in->disturbance = own.disturbance;
  }
  if (config_.compensation >= Compensation::kCooperative && !config_.leader) {
    in->plans = &plans_;
  }
  if (config_.compensation >= Compensation::kWake && !config_.leader) {
    const WakeSlots source = WakeSources(in->active, static_cast<int>(config_.neighbours.size()));
    for (const int j : source) {
      if (j < 0) continue;
      // The planned thrust now when the neighbour's plan is fresh (cooperative).
      PlanPrediction plan;
      const bool planned = in->plans != nullptr &&
                           plans_.Predict(j, t, 0.0, config_.plan_timeout,
                                          in->neighbours[j].rel_pos, in->neighbours[j].vel, &plan);
      const double thrust = planned ? plan.thrust : in->neighbours[j].thrust;
      in->wake.z() += wake_.Acceleration(-in->neighbours[j].rel_pos, thrust);
    }
    if (!in->wake.allFinite()) in->wake.setZero();
  }
  out->wake = in->wake;
  out->disturbance = in->disturbance + in->wake;
  plan_disturbance_ = out->disturbance;
  NearestObstacles(t, in);
  // Fault injection (SafetyConfig::injected_failure_rate, 0 = off).
  in->forced_failure =
      InjectedSolverFailure(config_.safety, config_.vehicle, t, config_.rti.sample_time);
}

// One NMPC step and the recovery ladder's decision on it; without a usable estimate, level
// attitude at hover thrust while the ladder counts.
Vec3 VehicleController::NmpcCommand(double t, double z, ControlOutput* out) {
  RecoveryDecision d;
  Vec3 command;
  if (EstimateUsable(t)) {
    NmpcInput in;
    FillNmpcInput(t, z, &in, out);
    if (reinit_pending_) {
      const Vec3 guess = in.last_command;
      nmpc_->Start(in, guess);
      reinit_pending_ = false;
      nmpc_started_ = true;
    }
    const NmpcStep s = nmpc_->Step(in);
    out->nmpc = true;
    plan_time_ = t;
    out->nmpc_thrust = s.u[0];
    out->nmpc_roll = s.u[1];
    out->nmpc_pitch = s.u[2];
    out->solver_time = s.stats.time_total;
    out->sqp_iterations = s.stats.sqp_iterations;
    out->qp_iterations = s.stats.qp_iterations;
    out->fallback = s.stats.fallback;
    out->status = s.stats.status;
    out->reference = s.reference;
    if (out->fallback) ++fallbacks_;
    double thrust = s.u[0];
    double roll = s.u[1] - applied_offset_[0];
    double pitch = s.u[2] - applied_offset_[1];
    Blend(t, &thrust, &roll, &pitch);
    command = Vec3(thrust, roll, pitch);
    d = ladder_.Update(t, true, out->fallback);
  } else {
    // No estimate to run on: level attitude at hover thrust, damped by the raw
    // motion-capture vertical speed while it is fresh and consistent, until the estimate
    // returns or the ladder's timeout hands over to the failsafe controller. (The last
    // NMPC thrust may belong to a climb or a descent: held, it drops or lifts the vehicle.)
    const double hover = config_.params.mass * kGravity;
    const bool raw = RawMocapFresh(t) && std::isfinite(raw_v_.z()) && !VelocityInconsistent(t);
    const double thrust = raw ? hover - config_.params.mass * config_.pid.kd_z * raw_v_.z() : hover;
    command = Vec3(std::clamp(thrust, 0.0, config_.pid.max_thrust), 0.0, 0.0);
    d = ladder_.Update(t, false, false);
  }
  out->recovery = d.action;
  out->recovery_reason = d.reason;
  if (d.action == RecoveryAction::kReinitialise) reinit_pending_ = true;
  if (d.action == RecoveryAction::kFailsafe) EnterFailsafe(t, d.reason);
  return command;
}

// Failsafe: hold the altitude with the attitude level, then descend; from the height if
// known, else from the vertical speed, else at a thrust just below hover.
Vec3 VehicleController::FailsafeCommand(double t, double dt) {
  const estimation::VehicleEstimate& own = estimates_.own;
  const double fs = config_.safety.recovery.failsafe_descent_speed;
  const bool descending = t - phase_start_ >= config_.safety.recovery.failsafe_hold_time;
  const double vz_ref = descending ? -fs : 0.0;
  const double hover = config_.params.mass * kGravity;
  const double zf = FailsafeHeight(t);
  const bool raw = RawMocapFresh(t);
  const double vz_meas = raw && std::isfinite(raw_v_.z()) ? raw_v_.z() : own.velocity.z();
  double thrust = kNaN;
  if (std::isfinite(zf)) {
    if (!std::isfinite(z_ref_)) z_ref_ = zf;
    if (descending) z_ref_ = std::max(config_.ground_height - 0.3, z_ref_ - fs * dt);
    // Level: no horizontal damping (the horizontal estimate may be what failed).
    const double vz = std::isfinite(vz_meas) ? vz_meas : 0.0;
    const PidCommand c = pid_.Update(dt, z_ref_, vz_ref, zf, Vec3(0.0, 0.0, vz), Vec3::Zero(),
                                     Vec<2>::Constant(kNaN));
    thrust = c.thrust;
    if (TouchedDown(t, zf, vz)) {
      phase_ = FlightPhase::kLanded;
      phase_start_ = t;
      thrust = 0.0;
    }
  } else if (std::isfinite(vz_meas) && !VelocityInconsistent(t)) {
    thrust = hover + config_.params.mass * config_.pid.kd_z * (vz_ref - vz_meas);
  } else {
    thrust = descending ? kFailsafeBlindThrustFactor * hover : hover;
  }
  double roll = 0.0, pitch = 0.0;
  if (raw && raw_v_.allFinite() && std::isfinite(raw_yaw_)) {
    // Motion capture left: brake the horizontal velocity too (the PID's damping).
    const PidCommand c =
        pid_.Update(0.0, zf, 0.0, zf, raw_v_, Vec3(0.0, 0.0, raw_yaw_), Vec<2>::Constant(kNaN));
    roll = c.roll;
    pitch = c.pitch;
  }
  return Vec3(std::clamp(thrust, 0.0, config_.pid.max_thrust), roll, pitch);
}

// The guard (a non-finite estimate or solution never becomes a command: the last valid one
// is repeated), the command's bookkeeping and the throttle.
void VehicleController::SendCommand(Vec3 command, double dt, ControlOutput* out) {
  if (!command.allFinite()) {
    out->guarded = true;
    command = last_command_.allFinite() ? last_command_ : Vec3(Vec3::Zero());
  } else {
    last_command_ = command;
    const double a = config_.blend_time > 0.0 ? 1.0 - std::exp(-dt / config_.blend_time) : 1.0;
    mean_thrust_ =
        std::isfinite(mean_thrust_) ? mean_thrust_ + a * (command[0] - mean_thrust_) : command[0];
  }
  if (phase_ == FlightPhase::kNmpc) attitude_offset_.Sent(command.tail<2>());
  out->phase = phase_;
  out->thrust = command[0];
  out->roll = command[1];
  out->pitch = command[2];
  if (config_.use_throttle && std::isfinite(voltage_)) {
    out->throttle = ThrustToThrottle(config_.params.throttle, command[0], voltage_);
  }
}

}  // namespace fnmpc::formation

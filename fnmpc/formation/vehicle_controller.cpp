// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/vehicle_controller.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/formation/neighbour_acceleration.hpp"
#include "fnmpc/formation/nmpc_core.hpp"

namespace fnmpc::formation {

std::string_view ToString(FlightPhase p) {
  switch (p) {
    case FlightPhase::kIdle:
      return "idle";
    case FlightPhase::kTakeoff:
      return "takeoff";
    case FlightPhase::kNmpc:
      return "nmpc";
    case FlightPhase::kLanding:
      return "landing";
    case FlightPhase::kLanded:
      return "landed";
    case FlightPhase::kFailsafe:
      return "failsafe";
  }
  return "?";
}

void ControllerConfig::Validate() const {
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("[ControllerConfig] " + what);
  };
  params.Validate();
  rti.Validate();
  if (vehicle < 0) fail("vehicle index must be >= 0, got " + std::to_string(vehicle));
  if (leader_vehicle < -1)
    fail("leader_vehicle must be >= -1, got " + std::to_string(leader_vehicle));
  if (!(thrust_min >= 0.0 && thrust_max > thrust_min)) fail("thrust bounds need 0 <= min < max");
  if (!(max_attitude_ref > 0.0 && max_attitude_ref < 1.2))
    fail("max_attitude_ref must be in (0, 1.2) rad");
  if (!(max_speed > 0.0)) fail("max_speed must be > 0");
  if (max_tracked < 1 || max_tracked > 64)
    fail("max_tracked must be in [1, 64], got " + std::to_string(max_tracked));
  const int level = static_cast<int>(compensation);
  if (level < 0 || level >= kCompensationChoice.count) {
    fail("compensation must be one of " + kCompensationChoice.Accepted());
  }
  if (level >= kCompensationChoice.available) {
    fail(std::string("compensation '") + ToString(compensation) +
         "' is not implemented yet (accepted: " + kCompensationChoice.Accepted() + ")");
  }
  if (!(plan_timeout > 0.0)) fail("plan_timeout must be > 0 s");
  if (!(attitude_offset_filter > 0.0) || !std::isfinite(attitude_offset_filter))
    fail("attitude_offset.filter_time must be finite and > 0 s");
  if (!(attitude_offset_max >= 0.0 && attitude_offset_max < max_attitude_ref))
    fail("attitude_offset.max must be in [0, bounds.attitude_ref)");
  const int rule = static_cast<int>(tie_weights);
  if (rule < 0 || rule >= kTieWeightingChoice.count)
    fail("tie_weights must be one of " + kTieWeightingChoice.Accepted());
  safety.Validate();
  if (!leader) {
    if (neighbours.empty() || neighbours.size() > static_cast<std::size_t>(kMaxNeighbours)) {
      fail("a follower needs 1 to " + std::to_string(kMaxNeighbours) + " neighbours, got " +
           std::to_string(neighbours.size()));
    }
    for (std::size_t i = 0; i < neighbours.size(); ++i) {
      const NeighbourTarget& n = neighbours[i];
      if (n.vehicle < 0 || n.vehicle == vehicle)
        fail("bad neighbour index " + std::to_string(n.vehicle));
      for (std::size_t j = 0; j < i; ++j) {
        if (neighbours[j].vehicle == n.vehicle)
          fail("neighbour " + std::to_string(n.vehicle) + " is listed twice");
      }
      if (!n.desired.allFinite()) fail("desired relative position must be finite");
    }
    if (!((relative_position_bound.array() > 0.0).all()))
      fail("relative_position_bound must be > 0");
  } else if (trajectory.empty()) {
    fail("the leader needs a trajectory");
  }
  if (!(takeoff_height > ground_height)) fail("takeoff_height must be above ground_height");
  if (!(climb_speed > 0.0) || !(descent_speed > 0.0)) fail("climb and descent speeds must be > 0");
  if (!(blend_time >= 0.0) || !(hover_before_switch >= 0.0))
    fail("blend_time, hover_before_switch >= 0");
  if (!(landing_time > takeoff_time)) fail("landing_time must be after takeoff_time");
  if (!(touchdown_margin > 0.0)) fail("touchdown_margin must be > 0");
  if (!(voltage_filter_time >= 0.0)) fail("voltage_filter_time must be >= 0");
  if (!(neighbour_acceleration_decay >= 0.0) || !std::isfinite(neighbour_acceleration_decay))
    fail("neighbour_acceleration.decay must be finite and >= 0");
  if (!(neighbour_acceleration_filter >= 0.0) || !std::isfinite(neighbour_acceleration_filter))
    fail("neighbour_acceleration.filter_time must be finite and >= 0");
  pid.Validate();
}

namespace {

estimation::VehicleEkfConfig OwnEkfConfig(const ControllerConfig& c) {
  estimation::VehicleEkfConfig e;
  e.sensors = c.sensors;
  e.vehicle = c.vehicle;
  e.ground_height = c.leader ? c.ground_height : 0.0;
  e.command_rate_hz = 1.0 / c.rti.sample_time;  // SetCommand once per control step
  return e;
}

/// Motion-capture height: older than this is not used, a longer gap restarts its rate [s].
constexpr double kMaxMocapGap = 0.5;
/// First-order filter of the motion-capture height's rate [s] (1 mm noise at 60 Hz: about
/// 0.03 m/s left).
constexpr double kMocapRateFilterTime = 0.1;
/// Motion-capture outliers: a sample farther than this from the raw track's prediction
/// (last sample plus rate times the interval) is skipped [m], unless it is the
/// kMocapGateRun-th in a row, which restarts the track. The prediction's error is a few mm
/// (1 mm noise, the 0.1 s rate filter's lag at 5 m/s^2 is 8 mm per 60 Hz interval).
constexpr double kMocapGate = 0.1;
constexpr int kMocapGateRun = 5;
/// Consistency check: EKF velocity against the motion-capture rate [m/s], for [s].
constexpr double kVelocityMismatch = 1.0;
constexpr double kVelocityMismatchTime = 0.3;
/// A vehicle in view takes the tracking slot of the farthest tracked one only when it is
/// nearer by this much [m] (measured ranges; the range noise is centimetres).
constexpr double kTrackSwapMargin = 0.5;
/// A neighbour whose estimated CoM is within this of the resting height is on the ground [m].
constexpr double kGroundedMargin = 0.15;

bool Rejected(estimation::EkfStatus s) {
  using estimation::EkfStatus;
  return s == EkfStatus::kRejectedNonFinite || s == EkfStatus::kRejectedGated ||
         s == EkfStatus::kRejectedTooOld || s == EkfStatus::kRejectedInvalid ||
         s == EkfStatus::kNumericalError || s == EkfStatus::kRejectedTimeJump;
}

}  // namespace

// ---------------------------------------------------------------------------------------

VehicleController::VehicleController(const ControllerConfig& config)
    : config_((config.Validate(), config)),
      ekf_(OwnEkfConfig(config), config.params),
      wake_(config.params),
      pid_(config.pid, config.params.mass),
      ladder_(config.safety.recovery),
      collision_sigmas_(CollisionSigmas(config.safety)),
      departure_(config.safety.neighbour_departure_height, config.safety.neighbour_departure_time,
                 config.safety.neighbour_reacquire_time) {
  for (const NeighbourTarget& n : config_.neighbours) {
    estimation::NeighbourEkfConfig nc;
    nc.sensors = config_.sensors;
    nc.observer = config_.vehicle;
    nc.target = n.vehicle;
    nc.own_velocity_rate_hz = 1.0 / config_.rti.sample_time;  // PredictTo once per step
    neighbour_ekfs_.emplace_back(nc);
  }
  // Tracking slots for the other vehicles in view: what max_tracked leaves after the
  // formation neighbours, all built now (no allocation when they change hands).
  const int others =
      config_.track_others
          ? std::max(0, config_.max_tracked - static_cast<int>(config_.neighbours.size()))
          : 0;
  tracks_.reserve(static_cast<std::size_t>(others));
  for (int k = 0; k < others; ++k) {
    estimation::NeighbourEkfConfig nc;
    nc.sensors = config_.sensors;
    nc.observer = config_.vehicle;
    nc.own_velocity_rate_hz = 1.0 / config_.rti.sample_time;
    tracks_.push_back(Track{-1, kNaN, kInf, estimation::NeighbourEkf(nc), Presence{}});
  }
  const std::size_t nn = config_.neighbours.size();
  estimates_.neighbours.assign(nn, estimation::NeighbourStateVec::Constant(kNaN));
  estimates_.others.assign(tracks_.size(), estimation::NeighbourStateVec::Constant(kNaN));
  estimates_.neighbour_covariances.assign(nn, estimation::NeighbourStateCov::Zero());
  estimates_.other_covariances.assign(tracks_.size(), estimation::NeighbourStateCov::Zero());
  presence_.assign(nn, Presence{});
  // A gap of more than two missed steps restarts the derivative.
  neighbour_acceleration_.assign(nn, AccelerationEstimate(config_.neighbour_acceleration_filter,
                                                          2.5 * config_.rti.sample_time));
  attitude_offset_ = AttitudeOffset(
      config_.params.attitude_time_constant.head<2>(), config_.params.attitude_gain.head<2>(),
      config_.attitude_offset_filter, config_.attitude_offset_max, 2.5 * config_.rti.sample_time);
  std::vector<int> neighbour_vehicles;
  for (const NeighbourTarget& n : config_.neighbours) neighbour_vehicles.push_back(n.vehicle);
  plans_ = NeighbourPlans(neighbour_vehicles);
  // The solver is built here, not at the take-off -> NMPC switch: no allocation in flight.
  if (config_.leader) {
    nmpc_ = MakeLeaderCore(config_);
  } else {
    nmpc_ = MakeFollowerCore(config_);
  }
}

VehicleController::~VehicleController() = default;
VehicleController::VehicleController(VehicleController&&) noexcept = default;
VehicleController& VehicleController::operator=(VehicleController&&) noexcept = default;

void VehicleController::Process(const Measurement& m) {
  if (m.vehicle != config_.vehicle) return;
  switch (m.kind) {
    case SensorKind::kMocapPose:
      // The leader fuses mocap; a follower has no absolute position: only the height is
      // kept, for the take-off and landing PID.
      if (config_.leader) ekf_.Process(m);
      TrackMocapPose(m);
      break;
    case SensorKind::kCompass:
      if (!config_.leader && !ekf_.initialized() && std::isfinite(m.yaw)) {
        ekf_.Initialize(m.stamp, Vec3::Zero(), Vec3(0.0, 0.0, m.yaw));  // origin of {m}
      }
      ekf_.Process(m);
      break;
    case SensorKind::kImu:
    case SensorKind::kOpticalFlow:
      ekf_.Process(m);
      break;
    case SensorKind::kBattery:
      if (std::isfinite(m.voltage) && m.voltage > 0.0) {
        if (!std::isfinite(voltage_)) {
          voltage_ = m.voltage;
        } else {
          const double dt = std::max(0.0, m.stamp - voltage_stamp_);
          const double a = config_.voltage_filter_time > 0.0
                               ? 1.0 - std::exp(-dt / config_.voltage_filter_time)
                               : 1.0;
          voltage_ += a * (m.voltage - voltage_);
        }
        voltage_stamp_ = m.stamp;
      }
      break;
    case SensorKind::kRelative: {
      if (!ekf_.initialized()) break;
      // The target's filter: a formation neighbour's or another sensed vehicle's.
      estimation::NeighbourEkf* filter = nullptr;
      Presence* presence = nullptr;
      for (std::size_t j = 0; j < config_.neighbours.size() && !filter; ++j) {
        if (config_.neighbours[j].vehicle != m.relative.target) continue;
        filter = &neighbour_ekfs_[j];
        presence = &presence_[j];
      }
      Track* track = nullptr;
      if (filter == nullptr && m.relative.target != config_.vehicle) {
        track = TrackOf(m.relative.target, m.stamp, m.relative.range);
        if (track != nullptr) {
          filter = &track->ekf;
          presence = &track->presence;
          if (std::isfinite(m.relative.range)) track->range = m.relative.range;
        }
      }
      if (filter == nullptr) break;
      const OwnAtStamp& own = OwnAt(m.stamp);
      if (filter->Process(m, own.euler, own.velocity, &own.euler_cov) ==
              estimation::EkfStatus::kAccepted &&
          std::isfinite(m.stamp)) {
        presence->Accept(m.stamp, config_.safety.neighbour_reacquire_time);
      }
      break;
    }
  }
}

const VehicleController::OwnAtStamp& VehicleController::OwnAt(double stamp) {
  OwnAtStamp& own = own_at_relative_;
  // NaN never equals itself: a non-finite stamp is predicted anew (and rejected downstream).
  if (own.stamp == stamp && own.revision == ekf_.revision()) return own;
  const estimation::VehicleEstimate e = ekf_.Estimate(stamp);
  own.stamp = stamp;
  own.revision = ekf_.revision();
  own.euler = e.euler;
  own.velocity = e.velocity;
  own.euler_cov = e.covariance.block<3, 3>(estimation::VehicleStateIndex::kEuler,
                                           estimation::VehicleStateIndex::kEuler);
  return own;
}

// The slot of another vehicle in view: its own, else a free one (never given, or its vehicle
// unmeasured for neighbour_timeout: out of view), else the slot of the farthest tracked
// vehicle when this one is nearer by kTrackSwapMargin (nearest first, without two vehicles
// at about the same range taking the slot from each other at every measurement). nullptr:
// not tracked. The slot's filter restarts for its new vehicle; no allocation.
VehicleController::Track* VehicleController::TrackOf(int vehicle, double stamp, double range) {
  for (Track& k : tracks_) {
    if (k.vehicle == vehicle) return &k;
  }
  if (!std::isfinite(stamp) || !std::isfinite(range)) return nullptr;
  Track* slot = nullptr;
  for (Track& k : tracks_) {
    if (k.vehicle < 0 || TrackLost(k, stamp)) {
      slot = &k;
      break;
    }
  }
  if (slot == nullptr) {
    for (Track& k : tracks_) {
      if (slot == nullptr || k.range > slot->range) slot = &k;
    }
    if (slot == nullptr || !(range + kTrackSwapMargin < slot->range)) return nullptr;
  }
  slot->vehicle = vehicle;
  slot->assigned = stamp;
  slot->range = range;
  slot->presence = Presence{};
  slot->ekf.Retarget(vehicle);
  return slot;
}

// A tracked vehicle with no accepted measurement (or, never accepted, since its slot was
// given) for neighbour_timeout at t: out of view; its slot is free.
bool VehicleController::TrackLost(const Track& k, double t) const {
  const double last = std::isfinite(k.presence.seen) ? k.presence.seen : k.assigned;
  return !(t - last <= config_.safety.neighbour_timeout);
}

void VehicleController::Presence::Accept(double stamp, double max_gap) {
  if (!std::isfinite(seen) || stamp - seen > max_gap) seen_since = stamp;
  seen = std::isfinite(seen) ? std::max(seen, stamp) : stamp;
}

std::int64_t VehicleController::estimator_rejections() const {
  std::int64_t n = 0;
  for (int s = 0; s < estimation::kNumEkfStatus; ++s) {
    if (!Rejected(static_cast<estimation::EkfStatus>(s))) continue;
    n += ekf_.counters().Total(static_cast<estimation::EkfStatus>(s));
    for (const auto& f : neighbour_ekfs_)
      n += f.counters().Total(static_cast<estimation::EkfStatus>(s));
    for (const Track& k : tracks_)
      n += k.ekf.counters().Total(static_cast<estimation::EkfStatus>(s));
  }
  return n;
}

// The take-off and landing PID's horizontal error: hold point minus the own position estimate
// (a follower's is dead-reckoned from its velocity, drift-free enough over one phase).
Vec<2> VehicleController::HoldError() const { return hold_xy_ - estimates_.own.position.head<2>(); }

double VehicleController::Height(double t) const {
  const auto& own = estimates_.own;
  if (config_.leader) return own.valid ? own.position.z() : kNaN;
  // A follower: the raw motion-capture height while it is fresh. A stale one would freeze
  // the height the take-off, landing and failsafe loops close on, and the failsafe's
  // descent would speed up towards its falling reference (fault campaign run 8: mocap lost
  // in the descent, touchdown at -0.8 m/s); after kMaxMocapGap the estimate's.
  if (RawMocapFresh(t)) return raw_z_;
  return own.valid ? config_.ground_height + own.position.z() : kNaN;
}

void VehicleController::Blend(double t, double* thrust, double* roll, double* pitch) const {
  if (!blend_from_.allFinite() || !(config_.blend_time > 0.0)) return;
  const double a = std::clamp((t - blend_start_) / config_.blend_time, 0.0, 1.0);
  *thrust = (1.0 - a) * blend_from_[0] + a * *thrust;
  *roll = (1.0 - a) * blend_from_[1] + a * *roll;
  *pitch = (1.0 - a) * blend_from_[2] + a * *pitch;
}

// Hysteresis on the neighbours' accepted relative measurements: lost after
// neighbour_timeout without one, back after a run of neighbour_reacquire_time. A neighbour
// seen on the ground (its estimated CoM height, own height plus the relative offset, within
// kGroundedMargin of the resting height) for neighbour_timeout is lost too: a landed or
// fallen vehicle cannot be kept in formation; it returns once airborne again for
// neighbour_reacquire_time.
void VehicleController::UpdateNeighbourPresence(double t) {
  const double z = Height(t);
  const SafetyConfig& sc = config_.safety;
  if (std::isfinite(nmpc_start_)) {  // neighbours leaving the formation (formation_ties.hpp)
    std::array<TieView, kMaxNeighbours> views;
    for (std::size_t j = 0; j < presence_.size(); ++j) {
      const Presence& p = presence_[j];
      const auto& x = estimates_.neighbours[j];
      views[j] = {x[2], config_.neighbours[j].desired.z(),
                  config_.neighbours[j].vehicle == config_.leader_vehicle,
                  std::isfinite(p.seen) && t - p.seen <= sc.neighbour_timeout &&
                      x.head<3>().allFinite() && !(p.landed && !p.active)};
    }
    departure_.Update(t, views.data(), static_cast<int>(presence_.size()));
  }
  UpdateLeaderSeenDown(t, z);
  for (std::size_t j = 0; j < presence_.size(); ++j) {
    Presence& p = presence_[j];
    const bool fresh = std::isfinite(p.seen) && t - p.seen <= sc.neighbour_timeout;
    const bool departed = departure_.departed(static_cast<int>(j));
    const double zj = z + estimates_.neighbours[j][2];
    const bool grounded = std::isfinite(zj) && zj < config_.ground_height + kGroundedMargin;
    p.grounded.Update(grounded, t);
    const bool landed = p.grounded.For(t, sc.neighbour_timeout);
    if (p.active && (!fresh || landed || departed) && std::isfinite(nmpc_start_)) {
      if (fresh && !landed) ++neighbour_departures_;
      p.active = false;
      p.landed = landed;
      p.airborne.Reset();
    } else if (!p.active && fresh && !grounded && !departed) {
      p.airborne.Start(t);
      const bool run = p.seen - p.seen_since >= sc.neighbour_reacquire_time;
      const bool airborne = !p.landed || p.airborne.For(t, sc.neighbour_reacquire_time);
      if (run && airborne) p.active = true;
    } else if (grounded) {
      p.airborne.Reset();
    }
  }
}

// The leader seen on the ground for neighbour_timeout in a tracking slot (a follower that
// does not have it as a formation neighbour but senses it; the same test as the neighbours').
void VehicleController::UpdateLeaderSeenDown(double t, double z) {
  leader_seen_down_ = false;
  if (config_.leader || config_.leader_vehicle < 0) return;
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    Presence& p = tracks_[k].presence;
    if (tracks_[k].vehicle != config_.leader_vehicle) continue;
    const double zl = z + estimates_.others[k][2];
    const bool fresh = std::isfinite(p.seen) && t - p.seen <= config_.safety.neighbour_timeout;
    p.grounded.Update(fresh && std::isfinite(zl) && zl < config_.ground_height + kGroundedMargin,
                      t);
    leader_seen_down_ = leader_seen_down_ || p.grounded.For(t, config_.safety.neighbour_timeout);
  }
}

// Every formation tie to the leader lost (TieLoss): the leader down, or every neighbour
// landed or gone from the formation.
RecoveryReason VehicleController::TieLossNow() const {
  std::array<TieState, kMaxNeighbours> ties;
  for (std::size_t j = 0; j < presence_.size(); ++j) {
    const Presence& p = presence_[j];
    ties[j] = {config_.neighbours[j].vehicle == config_.leader_vehicle, p.active,
               p.landed && !p.active, departure_.departed(static_cast<int>(j))};
  }
  return TieLoss(ties.data(), static_cast<int>(presence_.size()), leader_seen_down_);
}

// Raw motion-capture pose and its filtered rate, kept apart from the EKF: the failsafe and
// the consistency check must not depend on the estimate they check.
void VehicleController::TrackMocapPose(const Measurement& m) {
  if (!m.position.allFinite() || !std::isfinite(m.stamp)) return;
  const double dt = std::isfinite(raw_z_stamp_) ? m.stamp - raw_z_stamp_ : kInf;
  if (!(dt > 0.0)) return;  // out of order or repeated: keep the newer sample
  if (dt <= kMaxMocapGap && raw_v_.allFinite() &&
      (m.position - (raw_p_ + dt * raw_v_)).cwiseAbs().maxCoeff() > kMocapGate &&
      raw_rejected_in_row_ < kMocapGateRun) {
    ++raw_rejected_in_row_;  // an outlier: the raw height and rate skip it
    return;
  }
  const bool restart = raw_rejected_in_row_ >= kMocapGateRun;  // the track itself jumped
  raw_rejected_in_row_ = 0;
  if (dt <= kMaxMocapGap && !restart) {
    const double a = 1.0 - std::exp(-dt / kMocapRateFilterTime);
    const Vec3 rate = (m.position - raw_p_) / dt;
    raw_v_ = raw_v_.allFinite() ? Vec3(raw_v_ + a * (rate - raw_v_)) : rate;
  } else {
    raw_v_.setConstant(kNaN);  // a gap: restart the rate
  }
  raw_p_ = m.position;
  raw_z_ = m.position.z();
  raw_yaw_ = m.euler.z();
  raw_z_stamp_ = m.stamp;
}

bool VehicleController::RawMocapFresh(double t) const {
  return std::isfinite(raw_z_stamp_) && t - raw_z_stamp_ <= kMaxMocapGap;
}

// The EKF's velocity against the motion-capture rate: a disagreement above
// kVelocityMismatch on any axis for longer than kVelocityMismatchTime marks the estimate
// unusable (an integrating velocity estimate, e.g. without optical flow, diverges long
// before its covariance says so). Needs motion capture; without it nothing is checked.
void VehicleController::CheckVelocityConsistency(double t) {
  const Vec3& v = estimates_.own.velocity;
  if (!RawMocapFresh(t) || !raw_v_.allFinite() || !v.allFinite()) {
    velocity_mismatch_.Reset();
    return;
  }
  velocity_mismatch_.Update((v - raw_v_).cwiseAbs().maxCoeff() > kVelocityMismatch, t);
}

bool VehicleController::VelocityInconsistent(double t) const {
  return velocity_mismatch_.For(t, kVelocityMismatchTime);
}

// The NMPC can run on the estimate: the own state is valid and finite and (follower) at
// least one neighbour in the cost has a finite estimate.
bool VehicleController::EstimateUsable(double t) const {
  const auto& own = estimates_.own;
  if (!own.valid || !own.velocity.allFinite() || !own.euler.allFinite()) return false;
  if (VelocityInconsistent(t)) return false;
  if (config_.leader) return own.position.allFinite();
  bool any = false;
  for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
    if (presence_[j].active && estimates_.neighbours[j].allFinite()) any = true;
  }
  return any;
}

ControlOutput VehicleController::Control(double t) {
  estimates_.own = ekf_.initialized() ? ekf_.Estimate(t) : estimation::VehicleEstimate{};
  const estimation::VehicleEstimate& own = estimates_.own;
  // Every tracked vehicle predicted to t (NaN while its filter has nothing to go on).
  const auto predict = [&](estimation::NeighbourEkf& f, estimation::NeighbourStateVec& out,
                           estimation::NeighbourStateCov& cov) {
    if (f.initialized() && own.valid && own.velocity.allFinite()) {
      f.PredictTo(t, own.velocity);
      const estimation::NeighbourEstimate e = f.EstimateAt(t, own.velocity);
      out = e.x;
      cov = e.covariance;
    } else {
      out.setConstant(kNaN);
      cov.setZero();
    }
  };
  for (std::size_t j = 0; j < neighbour_ekfs_.size(); ++j) {
    predict(neighbour_ekfs_[j], estimates_.neighbours[j], estimates_.neighbour_covariances[j]);
  }
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    Track& track = tracks_[k];
    if (track.vehicle >= 0 && TrackLost(track, t)) track.vehicle = -1;  // out of view: free
    if (track.vehicle >= 0) {
      predict(track.ekf, estimates_.others[k], estimates_.other_covariances[k]);
    } else {
      estimates_.others[k].setConstant(kNaN);
      estimates_.other_covariances[k].setZero();
    }
  }
  UpdateNeighbourPresence(t);
  CheckVelocityConsistency(t);
  ControlOutput out = Step(t);
  // The wake model's part of the external acceleration (Compensation::kWake) is known to the
  // estimator, whose d then carries the rest only (no double counting in the prediction).
  if (ekf_.initialized()) ekf_.SetCommand(t, out.thrust, out.roll, out.pitch, out.yaw, out.wake);
  return out;
}

void VehicleController::Diagnose(ControlOutput* out) {
  if (out == nullptr || !out->nmpc || !nmpc_started_) return;
  nmpc_->Diagnose(&out->kkt, &out->cost);
}

bool VehicleController::ReceivePlan(const PlanMessage& m) { return plans_.Receive(m); }

bool VehicleController::MakePlan(PlanMessage* out) const {
  if (!std::isfinite(plan_time_) || phase_ != FlightPhase::kNmpc || !nmpc_started_) return false;
  out->vehicle = config_.vehicle;
  out->stamp = plan_time_;
  out->sample_time = config_.rti.sample_time;
  out->disturbance = plan_disturbance_.allFinite() ? plan_disturbance_ : Vec3(Vec3::Zero());
  nmpc_->Plan(out);
  return out->Valid();
}

std::vector<Vec3> VehicleController::PredictedPositions() const {
  std::vector<Vec3> out;
  if (phase_ != FlightPhase::kNmpc || !nmpc_started_) return out;
  const Vec3 origin =
      estimates_.own.position.allFinite() ? Vec3(estimates_.own.position) : Vec3(Vec3::Zero());
  nmpc_->Predicted(origin, &out);
  return out;
}

ControlOutput VehicleController::ControlWithEstimates(
    double t, const estimation::VehicleEstimate& own,
    const std::vector<estimation::NeighbourStateVec>& neighbours,
    const std::vector<estimation::NeighbourStateCov>* covariances) {
  estimates_.own = own;
  for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
    estimates_.neighbours[j] =
        j < neighbours.size() ? neighbours[j] : estimation::NeighbourStateVec::Constant(kNaN);
    estimates_.neighbour_covariances[j] = covariances != nullptr && j < covariances->size()
                                              ? (*covariances)[j]
                                              : estimation::NeighbourStateCov::Zero();
    // Given estimates count as fresh measurements of the neighbours they describe.
    if (estimates_.neighbours[j].allFinite()) {
      presence_[j].Accept(t, config_.safety.neighbour_reacquire_time);
    }
  }
  UpdateNeighbourPresence(t);
  CheckVelocityConsistency(t);
  return Step(t);
}

}  // namespace fnmpc::formation

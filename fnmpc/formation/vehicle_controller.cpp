// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/vehicle_controller.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/formation/neighbour_acceleration.hpp"
#include "fnmpc/formation/neighbour_thrust.hpp"
#include "fnmpc/formation/nmpc_core.hpp"
#include "fnmpc/formation/throttle_map.hpp"

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

/// Failsafe descent without height or vertical speed: a thrust just below hover (about
/// 0.3 m/s^2 down) so that the vehicle sinks slowly instead of holding an unknown height.
constexpr double kFailsafeBlindThrustFactor = 0.97;
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
/// Lateral shift of a sensed vehicle to the observer's left, as a fraction of r_min
/// (NearestObstacles: the passing rule).
constexpr double kPassingShift = 0.3;
/// A neighbour whose estimated CoM is within this of the resting height is on the ground [m].
constexpr double kGroundedMargin = 0.15;
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

// The kObstacleSlots nearest tracked vehicles (formation neighbours and others) with a
// finite estimate and an accepted measurement within neighbour_timeout: the last valid
// estimate is kept while it is that fresh. No allocation (fixed arrays).
template <class Input>
void VehicleController::NearestObstacles(double t, Input* in) const {
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
  const ControlOutput out = Step(t);
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

  double thrust = kNaN, roll = kNaN, pitch = kNaN;
  const double z = Height(t);
  const double ground = config_.ground_height;
  const double h = config_.takeoff_height;

  // ---- Phase logic.
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
  // its take-off then (waiting for a neighbour, below) lands instead of hovering on.
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
      out.recovery = RecoveryAction::kLand;
      out.recovery_reason = lost;
    }
  }

  switch (phase_) {
    case FlightPhase::kIdle:
    case FlightPhase::kLanded:
      thrust = roll = pitch = 0.0;
      break;
    case FlightPhase::kTakeoff: {
      if (PidEstimateLost(t, z, &out)) break;
      double vz_ref = 0.0;
      if (z_ref_ < h) {
        z_ref_ = std::min(h, z_ref_ + config_.climb_speed * dt);
        vz_ref = z_ref_ < h ? config_.climb_speed : 0.0;
      }
      const PidCommand c = pid_.Update(dt, z_ref_, vz_ref, z, own.velocity, own.euler, HoldError());
      thrust = c.thrust;
      roll = c.roll;
      pitch = c.pitch;
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
        out.recovery = RecoveryAction::kLand;
        out.recovery_reason = RecoveryReason::kNoNeighbourSeen;
        break;
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
      break;
    }
    case FlightPhase::kNmpc:
      break;  // below
    case FlightPhase::kLanding: {
      if (PidEstimateLost(t, z, &out)) break;
      // Not onto another vehicle: move the site clear, descend once not right above it.
      const bool wait = ClearLandingSite(t, &out);
      const double vz_ref = wait ? 0.0 : -config_.descent_speed;
      if (!wait) z_ref_ = std::max(ground - 0.3, z_ref_ - config_.descent_speed * dt);
      const PidCommand c = pid_.Update(dt, z_ref_, vz_ref, z, own.velocity, own.euler, HoldError());
      thrust = c.thrust;
      roll = c.roll;
      pitch = c.pitch;
      Blend(t, &thrust, &roll, &pitch);
      if (TouchedDown(t, z, own.velocity.z())) {
        phase_ = FlightPhase::kLanded;
        phase_start_ = t;
        thrust = roll = pitch = 0.0;
      }
      break;
    }
    case FlightPhase::kFailsafe:
      break;  // below
  }

  if (phase_ == FlightPhase::kNmpc) {
    RecoveryDecision d;
    if (EstimateUsable(t)) {
      NmpcInput in;
      in.t = t;
      in.position = own.position;
      in.own << own.velocity, own.euler;
      in.height = z;
      // Compensation::kWake: the neighbours' thrusts from their estimated accelerations.
      const bool wake_thrust = config_.compensation >= Compensation::kWake && !config_.leader;
      for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
        const auto& x = estimates_.neighbours[j];
        in.active[j] = presence_[j].active && x.allFinite();
        in.neighbours[j] = {x.segment<3>(0), x.segment<3>(3), x[6], x[7], Vec3::Zero(), kNaN};
        if (config_.neighbour_acceleration_decay > 0.0 || wake_thrust) {
          const Vec3 acc = MixedAcceleration(neighbour_ekfs_[j].hover_probability(),
                                             neighbour_acceleration_[j].Update(t, x.segment<3>(3)));
          if (config_.neighbour_acceleration_decay > 0.0) in.neighbours[j].acc = acc;
          if (wake_thrust) {
            // Once per neighbour and step (the horizon holds it): the wake model's thrust.
            const ThrustEstimate T = NeighbourThrust(config_, acc);
            in.neighbours[j].thrust = T.thrust;
            if (T.bound != ThrustBound::kNone) {
              ++out.neighbour_thrust_bounded;
              out.neighbour_thrust_bound = T.bound;
            }
          }
        }
      }
      in.last_command = last_command_.allFinite() ? last_command_
                                                  : Vec3(config_.params.mass * kGravity, 0.0, 0.0);
      // The NMPC's own input frame: the last reference sent plus the correction it carried.
      in.last_command.tail<2>() += applied_offset_;
      // Offset-free attitude (Compensation::kObserver on, after the blend from the take-off
      // PID): the offset estimate from the attitude measured now and the reference sent last
      // step, and the correction this step's reference carries (AttitudeOffset).
      if (config_.compensation >= Compensation::kObserver &&
          !(t < blend_start_ + config_.blend_time)) {
        attitude_offset_.Observe(t, own.euler.head<2>());
        applied_offset_ = attitude_offset_.reference_offset();
        nmpc_->ShiftAttitudeBounds(applied_offset_);
        out.attitude_offset_bounded = attitude_offset_.bounded();
      }
      out.attitude_offset = attitude_offset_.offset();
      // A non-finite estimate of d never enters the prediction (zero: today's controller).
      if (config_.compensation >= Compensation::kObserver && own.disturbance.allFinite()) {
        in.disturbance = own.disturbance;
      }
      if (config_.compensation >= Compensation::kCooperative && !config_.leader) {
        in.plans = &plans_;
      }
      if (config_.compensation >= Compensation::kWake && !config_.leader) {
        const WakeSlots source =
            WakeSources(in.active, static_cast<int>(config_.neighbours.size()));
        for (const int j : source) {
          if (j < 0) continue;
          // The planned thrust now when the neighbour's plan is fresh (cooperative).
          PlanPrediction plan;
          const bool planned =
              in.plans != nullptr &&
              plans_.Predict(j, t, 0.0, config_.plan_timeout, in.neighbours[j].rel_pos,
                             in.neighbours[j].vel, &plan);
          const double thrust = planned ? plan.thrust : in.neighbours[j].thrust;
          in.wake.z() += wake_.Acceleration(-in.neighbours[j].rel_pos, thrust);
        }
        if (!in.wake.allFinite()) in.wake.setZero();
      }
      out.wake = in.wake;
      out.disturbance = in.disturbance + in.wake;
      plan_disturbance_ = out.disturbance;
      NearestObstacles(t, &in);
      // Fault injection (SafetyConfig::injected_failure_rate, 0 = off).
      in.forced_failure =
          InjectedSolverFailure(config_.safety, config_.vehicle, t, config_.rti.sample_time);
      if (reinit_pending_) {
        const Vec3 guess = in.last_command;
        nmpc_->Start(in, guess);
        reinit_pending_ = false;
        nmpc_started_ = true;
      }
      const NmpcStep s = nmpc_->Step(in);
      out.nmpc = true;
      plan_time_ = t;
      out.nmpc_thrust = s.u[0];
      out.nmpc_roll = s.u[1];
      out.nmpc_pitch = s.u[2];
      out.solver_time = s.stats.time_total;
      out.sqp_iterations = s.stats.sqp_iterations;
      out.qp_iterations = s.stats.qp_iterations;
      out.fallback = s.stats.fallback;
      out.status = s.stats.status;
      out.reference = s.reference;
      if (out.fallback) ++fallbacks_;
      thrust = s.u[0];
      roll = s.u[1] - applied_offset_[0];
      pitch = s.u[2] - applied_offset_[1];
      Blend(t, &thrust, &roll, &pitch);
      d = ladder_.Update(t, true, out.fallback);
    } else {
      // No estimate to run on: level attitude at hover thrust, damped by the raw
      // motion-capture vertical speed while it is fresh and consistent, until the estimate
      // returns or the ladder's timeout hands over to the failsafe controller. (The last
      // NMPC thrust may belong to a climb or a descent: held, it drops or lifts the vehicle.)
      const double hover = config_.params.mass * kGravity;
      const bool raw = RawMocapFresh(t) && std::isfinite(raw_v_.z()) && !VelocityInconsistent(t);
      thrust = raw ? hover - config_.params.mass * config_.pid.kd_z * raw_v_.z() : hover;
      thrust = std::clamp(thrust, 0.0, config_.pid.max_thrust);
      roll = pitch = 0.0;
      d = ladder_.Update(t, false, false);
    }
    out.recovery = d.action;
    out.recovery_reason = d.reason;
    if (d.action == RecoveryAction::kReinitialise) reinit_pending_ = true;
    if (d.action == RecoveryAction::kFailsafe) EnterFailsafe(t, d.reason);
  }

  if (phase_ == FlightPhase::kFailsafe) {
    // Hold the altitude with the attitude level, then descend; from the height if known,
    // else from the vertical speed, else at a thrust just below hover.
    const double fs = config_.safety.recovery.failsafe_descent_speed;
    const bool descending = t - phase_start_ >= config_.safety.recovery.failsafe_hold_time;
    const double vz_ref = descending ? -fs : 0.0;
    const double hover = config_.params.mass * kGravity;
    const double zf = FailsafeHeight(t);
    const bool raw = RawMocapFresh(t);
    const double vz_meas = raw && std::isfinite(raw_v_.z()) ? raw_v_.z() : own.velocity.z();
    if (std::isfinite(zf)) {
      if (!std::isfinite(z_ref_)) z_ref_ = zf;
      if (descending) z_ref_ = std::max(ground - 0.3, z_ref_ - fs * dt);
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
    roll = pitch = 0.0;
    if (raw && raw_v_.allFinite() && std::isfinite(raw_yaw_)) {
      // Motion capture left: brake the horizontal velocity too (the PID's damping).
      const PidCommand c =
          pid_.Update(0.0, zf, 0.0, zf, raw_v_, Vec3(0.0, 0.0, raw_yaw_), Vec<2>::Constant(kNaN));
      roll = c.roll;
      pitch = c.pitch;
    }
    thrust = std::clamp(thrust, 0.0, config_.pid.max_thrust);
  }

  // ---- Guard: a non-finite estimate or solution never becomes a command.
  if (!std::isfinite(thrust) || !std::isfinite(roll) || !std::isfinite(pitch)) {
    out.guarded = true;
    if (last_command_.allFinite()) {
      thrust = last_command_[0];
      roll = last_command_[1];
      pitch = last_command_[2];
    } else {
      thrust = roll = pitch = 0.0;
    }
  } else {
    last_command_ = Vec3(thrust, roll, pitch);
    const double a = config_.blend_time > 0.0 ? 1.0 - std::exp(-dt / config_.blend_time) : 1.0;
    mean_thrust_ =
        std::isfinite(mean_thrust_) ? mean_thrust_ + a * (thrust - mean_thrust_) : thrust;
  }
  if (phase_ == FlightPhase::kNmpc) attitude_offset_.Sent(Vec<2>(roll, pitch));
  out.phase = phase_;
  out.thrust = thrust;
  out.roll = roll;
  out.pitch = pitch;
  if (config_.use_throttle && std::isfinite(voltage_)) {
    out.throttle = ThrustToThrottle(config_.params.throttle, thrust, voltage_);
  }
  return out;
}

}  // namespace fnmpc::formation

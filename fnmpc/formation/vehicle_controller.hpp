// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "fnmpc/core/held_for.hpp"
#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/estimation/neighbour_ekf.hpp"
#include "fnmpc/estimation/vehicle_ekf.hpp"
#include "fnmpc/formation/attitude_offset.hpp"
#include "fnmpc/formation/controller_settings.hpp"
#include "fnmpc/formation/formation_ties.hpp"
#include "fnmpc/formation/neighbour_acceleration.hpp"
#include "fnmpc/formation/neighbour_limits.hpp"
#include "fnmpc/formation/neighbour_plan.hpp"
#include "fnmpc/formation/neighbour_thrust.hpp"
#include "fnmpc/formation/nmpc_weights.hpp"
#include "fnmpc/formation/recovery.hpp"
#include "fnmpc/formation/takeoff_pid.hpp"
#include "fnmpc/formation/trajectory.hpp"
#include "fnmpc/model/vehicle_params.hpp"
#include "fnmpc/model/wake_force.hpp"
#include "fnmpc/ocp/problems.hpp"
#include "fnmpc/rti/rti_solver.hpp"

/// Per-vehicle cascaded formation controller of the reference work (Fig. 2): estimators
/// (VehicleEkf, one NeighbourEkf per neighbour) -> NMPC (RTI, Algorithm 1) -> autopilot
/// thrust/throttle and attitude references, with a PID take-off, a smooth switch to the
/// NMPC and a PID landing. No files, no YAML, no simulator: the app wires it.
namespace fnmpc::formation {

/// One neighbour of a follower: its vehicle index and the desired relative position
/// d_j = p_j - p_self [m], in {m} (world axes) or {c} (rotated by the follower's yaw).
struct NeighbourTarget {
  int vehicle = -1;
  Vec3 desired = Vec3::Zero();
  /// The neighbour's graph depth: fewest formation ties from the leader (formation::TieDepths,
  /// computed by whoever builds the formation); -1 unknown. Ranks the ties for
  /// ControllerSettings::tie_weights.
  int depth = -1;
};

/// Phases of a flight.
enum class FlightPhase : int {
  kIdle = 0,      ///< on the ground, motors off, estimators converging
  kTakeoff = 1,   ///< PID climb to the take-off height
  kNmpc = 2,      ///< NMPC in control (first blend_time blended from the PID's last command)
  kLanding = 3,   ///< PID descent
  kLanded = 4,    ///< touched down, motors off
  kFailsafe = 5,  ///< failsafe controller: level hover, then descent (see RecoveryLadder)
};
std::string_view ToString(FlightPhase p);

/// Everything one vehicle's controller is built from: the shared settings and what is its
/// own.
struct ControllerConfig : ControllerSettings {
  int vehicle = 0;              ///< index of the vehicle (its sensors' `vehicle` field)
  bool leader = false;          ///< leader: tracks `trajectory`; follower: keeps the formation
  model::VehicleParams params;  ///< vehicle model (mass, attitude model, throttle polynomial)
  SensorsConfig sensors;        ///< sensor noise for the estimators
  NmpcWeights weights;
  /// Track the other vehicles the relative sensor reports (not formation neighbours) for
  /// collision avoidance, in the max_tracked - (neighbour count) slots left; false: only the
  /// formation neighbours are tracked and avoided.
  bool track_others = false;
  /// Vehicle index of the formation's leader (-1: unknown). A follower checks its neighbours
  /// against it (NeighbourDeparture) and lands when it is down (TieLoss).
  int leader_vehicle = -1;
  // Follower only.
  std::vector<NeighbourTarget> neighbours;               ///< 1 to kMaxNeighbours, distinct
  ocp::TargetFrame frame = ocp::TargetFrame::kInertial;  ///< frame of `desired`
  Vec3 relative_position_bound{6.0, 6.0, 2.0};           ///< soft |dx_j,i| bounds [m]
  // Leader only: reference offsets from the hover point, from trajectory_start [s].
  WaypointTrajectory trajectory;
  double ground_height = 0.1;      ///< CoM height when resting on the ground [m]
  double touchdown_margin = 0.03;  ///< touchdown: within this of the ground, |v_z| < 0.1 m/s [m]
  TakeoffPidConfig pid;
  double voltage_filter_time = 0.3;  ///< first-order filter on the battery voltage [s]

  /// Throws std::invalid_argument with the field name on an inconsistent value.
  void Validate() const;
};

/// Command and diagnostics of one control step.
struct ControlOutput {
  double time = kNaN;
  FlightPhase phase = FlightPhase::kIdle;
  double thrust = 0.0;                        ///< commanded collective thrust [N]
  double throttle = kNaN;                     ///< collective throttle [0, 1] (NaN: use thrust)
  double roll = 0.0, pitch = 0.0, yaw = 0.0;  ///< attitude references [rad]
  bool guarded = false;  ///< a non-finite command was replaced by the last valid one
  // NMPC (valid when phase == kNmpc).
  bool nmpc = false;
  double nmpc_thrust = kNaN, nmpc_roll = kNaN, nmpc_pitch = kNaN;  ///< unblended NMPC output
  double cost = kNaN;  ///< NMPC objective of the iterate after the step
  double kkt = kNaN;   ///< KKT value after the step
  /// Wall time of the RTI step (steady clock, RtiStats::time_total; 0 for an injected
  /// failure, which does not solve) [s]
  double solver_time = kNaN;
  int sqp_iterations = 0, qp_iterations = 0;
  bool fallback = false;
  rti::RtiStatus status = rti::RtiStatus::kSuccess;
  /// Recovery ladder: the action taken at this step and why (kNone: nothing happened).
  RecoveryAction recovery = RecoveryAction::kNone;
  RecoveryReason recovery_reason = RecoveryReason::kNone;
  int active_neighbours = 0;  ///< follower: neighbours in the cost at this step
  /// External acceleration the NMPC predicted with at the current time ({n} axes) [m/s^2]:
  /// the estimator's d plus `wake`; zero with Compensation::kNone, NaN outside the NMPC.
  Vec3 disturbance = Vec3::Constant(kNaN);
  /// Compensation::kWake, follower: the wake model's part of `disturbance` (the neighbours'
  /// wakes at the current relative positions, model::WakeForceModel), passed to the estimator
  /// as known; zero otherwise [m/s^2].
  Vec3 wake = Vec3::Zero();
  /// Compensation::kWake, follower: neighbours whose thrust estimate (from their estimated
  /// acceleration, neighbour_thrust.hpp) was bounded at this step, and the last one's reason.
  int neighbour_thrust_bounded = 0;
  ThrustBound neighbour_thrust_bound = ThrustBound::kNone;
  /// Compensation::kObserver on: the attitude offset estimate o_hat (roll, pitch) [rad] the
  /// reference sent carries o_hat / k against (AttitudeOffset); NaN outside the NMPC.
  Vec<2> attitude_offset = Vec<2>::Constant(kNaN);
  /// That estimate was cut at +-`attitude_offset.max` at this step.
  bool attitude_offset_bounded = false;
  Vec3 reference = Vec3::Constant(kNaN);  ///< leader position reference [m]
  double voltage = kNaN;                  ///< filtered measured battery voltage [V]
};

/// Estimates the controller used at one step (for logs).
struct ControllerEstimates {
  estimation::VehicleEstimate own;
  std::vector<estimation::NeighbourStateVec> neighbours;  ///< NeighbourStateIndex layout
  /// Per tracking slot of the other vehicles (VehicleController::tracked_vehicle): its
  /// estimate, NaN while the slot is free or its filter has nothing to go on.
  std::vector<estimation::NeighbourStateVec> others;
  /// Covariances of `neighbours` and `others` (zero when not known: given estimates taken as
  /// exact); the collision avoidance's margin (SafetyConfig::collision_confidence).
  std::vector<estimation::NeighbourStateCov> neighbour_covariances, other_covariances;
};

class NmpcCore;  // leader or reduced follower solver (nmpc_core.hpp)
struct NmpcInput;

/// The controller of one vehicle. Feed every measurement with Process() as it arrives and
/// call Control(t) every Ts; Control never returns a non-finite command.
class VehicleController {
 public:
  /// Throws std::invalid_argument on an invalid config.
  explicit VehicleController(const ControllerConfig& config);
  ~VehicleController();
  VehicleController(VehicleController&&) noexcept;
  VehicleController& operator=(VehicleController&&) noexcept;

  /// Routes one measurement to the estimators (others' measurements are ignored).
  void Process(const Measurement& m);
  /// One control step at time t [s]: estimate -> NMPC or PID -> command. The command path
  /// only: call Diagnose() after the command was sent for the KKT value and the cost.
  ControlOutput Control(double t);
  /// Fills out->kkt and out->cost of the NMPC step that produced `out` (the last one).
  /// Costs N more integrations; outside the command path.
  void Diagnose(ControlOutput* out);
  /// Hands over to the failsafe controller now (fault injection, operator).
  void TriggerFailsafe(double t);
  /// The same step with the estimates given instead of taken from the filters (own state
  /// in {n} for the leader, {m} for a follower; neighbours in NeighbourStateIndex layout, one
  /// per configured neighbour). For tests and external estimators; NaN entries are allowed
  /// and never become a command. `covariances` (optional, one per neighbour): those of the
  /// neighbour estimates, else they count as exact.
  ControlOutput ControlWithEstimates(
      double t, const estimation::VehicleEstimate& own,
      const std::vector<estimation::NeighbourStateVec>& neighbours,
      const std::vector<estimation::NeighbourStateCov>* covariances = nullptr);

  [[nodiscard]] FlightPhase phase() const { return phase_; }
  [[nodiscard]] const ControllerConfig& config() const { return config_; }
  /// Estimator rejections so far (gated, non-finite, too old, invalid, numerical) over
  /// all of this vehicle's filters.
  [[nodiscard]] std::int64_t estimator_rejections() const;
  /// Number of NMPC fallbacks so far.
  [[nodiscard]] long fallbacks() const { return fallbacks_; }
  /// Solver re-initialisations by the recovery ladder so far.
  [[nodiscard]] long reinitialisations() const { return ladder_.reinitialisations(); }
  /// Whether the failsafe controller took over, and why.
  [[nodiscard]] bool failsafe() const { return ladder_.failsafe(); }
  [[nodiscard]] RecoveryReason failsafe_reason() const { return failsafe_reason_; }
  /// Times the landing moved its site clear of a sensed vehicle below (docs/safety.md).
  [[nodiscard]] long landing_site_shifts() const { return landing_site_shifts_; }
  /// Follower: whether neighbour j (configuration order) is in the cost.
  [[nodiscard]] bool neighbour_active(std::size_t j) const { return presence_.at(j).active; }
  /// Follower: whether neighbour j left the formation (NeighbourDeparture, docs/safety.md).
  [[nodiscard]] bool neighbour_departed(std::size_t j) const {
    return departure_.departed(static_cast<int>(j));
  }
  /// Follower: times a neighbour left its cost because it left the formation.
  [[nodiscard]] long neighbour_departures() const { return neighbour_departures_; }
  /// Follower: why it landed for want of a formation tie to the leader (kNone: it did not).
  [[nodiscard]] RecoveryReason tie_loss() const { return tie_loss_; }
  /// Tracking slots for the other vehicles in view (max_tracked minus the formation
  /// neighbours, or 0 without track_others).
  [[nodiscard]] int other_slots() const { return static_cast<int>(tracks_.size()); }
  /// Vehicle tracked in slot k of the others, -1 when the slot is free.
  [[nodiscard]] int tracked_vehicle(int k) const { return tracks_.at(k).vehicle; }
  /// Estimates used by the last Control() call.
  [[nodiscard]] const ControllerEstimates& estimates() const { return estimates_; }
  /// Start of the NMPC phase [s] (NaN before).
  [[nodiscard]] double nmpc_start() const { return nmpc_start_; }
  /// Leader: anchor of the trajectory (hover point at the switch) [m].
  [[nodiscard]] const Vec3& anchor() const { return anchor_; }
  /// Positions predicted by the last NMPC step over its horizon (N + 1 points; empty
  /// outside the NMPC phase) [m]: leader in {n}; follower in {m}, i.e. its own estimated
  /// position plus the predicted displacement. For display (ROS nav_msgs/Path); allocates.
  [[nodiscard]] std::vector<Vec3> PredictedPositions() const;
  /// Cooperative mode (Compensation::kCooperative): stores a plan published by a formation
  /// neighbour (valid and newer than the one held; NeighbourPlans); the next control steps
  /// predict that neighbour along it while it is younger than `plan_timeout`. Returns
  /// whether it was stored. No allocation.
  bool ReceivePlan(const PlanMessage& m);
  /// This vehicle's plan from its last control step into *out, to publish (no allocation);
  /// false when that step did not run the NMPC (nothing to publish).
  bool MakePlan(PlanMessage* out) const;
  /// Cooperative mode: the neighbours' plans held (configuration order).
  [[nodiscard]] const NeighbourPlans& neighbour_plans() const { return plans_; }

 private:
  // The flight phases (vehicle_controller_phases.cpp).
  ControlOutput Step(double t);
  void UpdatePhase(double t, double z, ControlOutput* out);
  Vec3 TakeoffCommand(double t, double dt, double z, ControlOutput* out);
  Vec3 LandingCommand(double t, double dt, double z, ControlOutput* out);
  void FillNmpcInput(double t, double z, NmpcInput* in, ControlOutput* out);
  Vec3 NmpcCommand(double t, double z, ControlOutput* out);
  Vec3 FailsafeCommand(double t, double dt);
  void SendCommand(Vec3 command, double dt, ControlOutput* out);
  double Height(double t) const;
  [[nodiscard]] Vec<2> HoldError() const;
  void Blend(double t, double* thrust, double* roll, double* pitch) const;
  bool EstimateUsable(double t) const;
  void UpdateNeighbourPresence(double t);
  void UpdateLeaderSeenDown(double t, double z);
  [[nodiscard]] RecoveryReason TieLossNow() const;
  void BeginLanding(double t, double z);
  void EnterFailsafe(double t, RecoveryReason reason);
  bool PidEstimateLost(double t, double z, ControlOutput* out);
  bool TouchedDown(double t, double z, double vz);
  bool ClearLandingSite(double t, ControlOutput* out);
  void NearestObstacles(double t, NmpcInput* in) const;
  void TrackMocapPose(const Measurement& m);
  bool RawMocapFresh(double t) const;
  double FailsafeHeight(double t) const;
  void CheckVelocityConsistency(double t);
  bool VelocityInconsistent(double t) const;

  ControllerConfig config_;
  estimation::VehicleEkf ekf_;
  /// The own attitude, velocity and attitude covariance a relative measurement is fused
  /// with, predicted to its stamp: the sensor measures every vehicle in view at one stamp,
  /// so one prediction serves them all while the filter is unchanged (its revision).
  struct OwnAtStamp {
    double stamp = kNaN;
    std::uint64_t revision = 0;
    Vec3 euler = Vec3::Zero();
    Vec3 velocity = Vec3::Zero();
    Mat3 euler_cov = Mat3::Zero();
  };
  OwnAtStamp own_at_relative_;
  const OwnAtStamp& OwnAt(double stamp);
  std::vector<estimation::NeighbourEkf> neighbour_ekfs_;
  /// Presence of a tracked vehicle, from the relative measurements its filter accepted.
  struct Presence {
    double seen = kNaN;        // stamp of the last accepted measurement [s]
    double seen_since = kNaN;  // start of the current run of acceptances [s]
    HeldFor grounded;          // seen on the ground (formation neighbours only)
    HeldFor airborne;          // airborne again after landing
    bool active = true;        // formation neighbour in the cost
    bool landed = false;       // lost because seen on the ground
    /// Records an acceptance at `stamp`; a gap longer than `max_gap` starts a new run.
    void Accept(double stamp, double max_gap);
  };
  /// A tracking slot for another vehicle in view (collision avoidance): the vehicle (-1:
  /// free), when the slot was given to it and its last measured range.
  struct Track {
    int vehicle = -1;
    double assigned = kNaN;  // [s]
    double range = kInf;     // [m]
    estimation::NeighbourEkf ekf;
    Presence presence;
  };
  // Fixed pool (built with the controller): no allocation when slots change hands.
  std::vector<Track> tracks_;
  Track* TrackOf(int vehicle, double stamp, double range);
  bool TrackLost(const Track& k, double t) const;
  std::unique_ptr<NmpcCore> nmpc_;
  model::WakeForceModel wake_;  // Compensation::kWake (follower): the neighbours' wakes
  TakeoffPid pid_;
  FlightPhase phase_ = FlightPhase::kIdle;
  double phase_start_ = 0.0;
  double nmpc_start_ = kNaN;
  double last_time_ = kNaN;
  HeldFor at_height_;              // take-off: at the take-off height
  double height_error_lp_ = kNaN;  // take-off: low-passed height error [m]
  // Take-off completion: low-passed height error within the tolerance (the former
  // every-sample band) and every sample within three times it, so the NMPC never takes over
  // far from the take-off height.
  static constexpr double kAtHeightTolerance = 0.05;  // [m]
  static constexpr double kAtHeightBand = 0.15;       // [m]
  double z_ref_ = kNaN;
  // Horizontal position the take-off and landing PID holds (own estimate, {n} x, y), set
  // when the phase starts; NaN = velocity damping only.
  Vec<2> hold_xy_ = Vec<2>::Constant(kNaN);
  double land_z0_ = kNaN;
  HeldFor contact_;  // the current ground contact (TouchedDown)
  long landing_site_shifts_ = 0;
  double site_wait_start_ = kNaN;  // start of the landing's current wait above a vehicle [s]
  double voltage_ = kNaN;          // filtered battery voltage
  double voltage_stamp_ = kNaN;
  double yaw_ref_ = kNaN;
  Vec3 anchor_ = Vec3::Constant(kNaN);
  Vec3 blend_from_ = Vec3::Constant(kNaN);  // (thrust, roll, pitch) at the last switch
  double blend_start_ = kNaN;
  Vec3 last_command_ = Vec3::Constant(kNaN);  // last valid (thrust, roll, pitch)
  // The valid thrust commands averaged over blend_time (first-order, [N]): what the landing
  // PID starts from. A single command is a poor start where the NMPC alternates (at the
  // altitude bound its thrust swings 11-17 N from step to step; stress/leader-lands-early).
  double mean_thrust_ = kNaN;
  long fallbacks_ = 0;
  ControllerEstimates estimates_;
  RecoveryLadder ladder_;
  double collision_sigmas_ = 0.0;  // CollisionSigmas(config_.safety)
  // Raw motion-capture pose [m, rad], its stamp [s] and filtered rate [m/s]; a disagreement
  // between that rate and the EKF's velocity.
  double raw_z_ = kNaN, raw_z_stamp_ = kNaN, raw_yaw_ = kNaN;
  Vec3 raw_p_ = Vec3::Constant(kNaN), raw_v_ = Vec3::Constant(kNaN);
  int raw_rejected_in_row_ = 0;  // motion-capture samples off the raw track (outliers)
  HeldFor velocity_mismatch_;
  RecoveryReason failsafe_reason_ = RecoveryReason::kNone;
  bool nmpc_started_ = false;
  bool reinit_pending_ = false;
  // Follower: neighbour presence (hysteresis on accepted relative measurements).
  std::vector<Presence> presence_;  // formation neighbours, configuration order
  // Follower: the formation neighbours' acceleration estimates (neighbour_acceleration_decay).
  std::vector<AccelerationEstimate> neighbour_acceleration_;
  // Offset-free attitude (Compensation::kObserver on): the estimate, and the correction
  // (o_hat / k) the last NMPC reference sent carried, subtracted from the NMPC's u.
  AttitudeOffset attitude_offset_;
  Vec<2> applied_offset_ = Vec<2>::Zero();
  NeighbourPlans plans_;                  // cooperative: the formation neighbours' latest plans
  double plan_time_ = kNaN;               // time of the last NMPC step (MakePlan) [s]
  Vec3 plan_disturbance_ = Vec3::Zero();  // its predicted external acceleration [m/s^2]
  NeighbourDeparture departure_;          // neighbours leaving the formation (formation_ties.hpp)
  bool leader_seen_down_ = false;         // the leader on the ground in a tracking slot
  RecoveryReason tie_loss_ = RecoveryReason::kNone;
  long neighbour_departures_ = 0;
};

}  // namespace fnmpc::formation

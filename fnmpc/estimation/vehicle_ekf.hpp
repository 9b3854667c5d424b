// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstdint>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/estimation/ekf_math.hpp"
#include "fnmpc/estimation/ekf_types.hpp"
#include "fnmpc/estimation/replay_buffer.hpp"
#include "fnmpc/model/vehicle_params.hpp"

namespace fnmpc::estimation {

/// Index of each entry of the VehicleEkf state x (18 entries), frame {n} (ENU, z up).
struct VehicleStateIndex {
  static constexpr int kPos = 0;        ///< position p [m], 3
  static constexpr int kVel = 3;        ///< velocity v [m/s], 3
  static constexpr int kEuler = 6;      ///< roll, pitch, yaw (ZYX) [rad], 3
  static constexpr int kAccelBias = 9;  ///< accelerometer bias, body frame [m/s^2], 3
  static constexpr int kGyroBias = 12;  ///< gyro bias, body frame [rad/s], 3
  /// External acceleration d, frame {n} [m/s^2], 3: what the thrust model leaves
  /// unexplained, v' = BodyZ(euler) T s / m - g e3 + d (wind, wakes, thrust-scale and mass
  /// errors); the external force is m d. Random walk (VehicleEkfConfig::disturbance_noise).
  static constexpr int kDisturbance = 15;
  static constexpr int kSize = 18;
};
using VehicleStateVec = Vec<VehicleStateIndex::kSize>;
using VehicleStateCov = Mat<VehicleStateIndex::kSize, VehicleStateIndex::kSize>;

/// Which model propagates the state while flying.
enum class MotionModel : int {
  kImu = 0,      ///< strapdown: v' = R(f - b_a) - g e3, euler' = T(euler)(w - b_g)
  kCommand = 1,  ///< first-order attitude + thrust: v' = BodyZ(euler) T/m - g e3
};

/// Settings of VehicleEkf. Noise standard deviations of the sensors come from `sensors`
/// (the simulator's defaults unless overridden); the rest are filter tuning values.
struct VehicleEkfConfig {
  SensorsConfig sensors;  ///< rates [Hz] and white-noise std per sensor (see core/sensors.hpp)
  int vehicle = -1;       ///< accept only measurements with this vehicle index; -1 = any
  MotionModel motion_model = MotionModel::kImu;     ///< flying model
  VehicleMode initial_mode = VehicleMode::kLanded;  ///< mode at initialisation
  bool auto_mode_switch = true;  ///< detect take-off and landing; false = stay in initial_mode
  /// Ground height in {n} [m] used when initialised flying (landed: the initial height).
  double ground_height = 0.0;

  // Multi-rate handling.
  double max_lag = 0.3;  ///< replay window: older measurements are dropped [s]
  /// Replay buffer entries; 0: ReplayCapacity of max_lag for the enabled sensors' rates and
  /// command_rate_hz (what the window holds).
  int buffer_capacity = 0;
  double command_rate_hz = 20.0;  ///< rate of SetCommand calls (the control rate) [Hz]
  double max_predict_dt = 0.01;   ///< longest single prediction sub-step [s]
  double imu_timeout = 0.05;      ///< IMU older than this: constant-velocity fallback [s]
  double command_timeout = 0.2;   ///< command older than this is not used [s]

  // Process noise (continuous-time spectral densities, as std per sqrt(s)).
  double accel_bias_noise = 1e-3;        ///< accel bias random walk [m/s^2/sqrt(s)]
  double gyro_bias_noise = 1e-4;         ///< gyro bias random walk [rad/s/sqrt(s)]
  double fallback_accel_noise = 3.0;     ///< accel white noise without IMU [m/s^2/sqrt(Hz)]
  double command_accel_noise = 0.5;      ///< command model acceleration error [m/s^2/sqrt(Hz)]
  double command_attitude_noise = 0.05;  ///< command model attitude error [rad/sqrt(s)]
  double landed_position_noise = 1e-3;   ///< landed position random walk [m/sqrt(s)]
  double landed_attitude_noise = 1e-3;   ///< landed attitude random walk [rad/sqrt(s)]
  double zupt_std = 0.005;               ///< landed zero-velocity pseudo-measurement std [m/s]
  /// Floors of the landed IMU updates' std per axis: the error of the resting model
  /// f = R^T g e3 + b_a, w = b_g (contact settling, motors spinning up, handling), which a
  /// near-ideal IMU's noise does not cover. The default sensors' IMU noise, so the default
  /// configuration is unchanged (docs/estimation.md).
  double landed_accel_std = 0.05;  ///< [m/s^2]
  double landed_gyro_std = 0.005;  ///< [rad/s]
  /// Random walk of the external acceleration d while flying [m/s^2/sqrt(s)]. Default from
  /// the physics of what d stands for: a change of 0.1 g within about 1 s (a gust front, a
  /// neighbour's wake entered at 1 m/s: its half-width of a few decimetres is crossed in
  /// well under a second), i.e. 0.1 * 9.81 / sqrt(1 s). Not tuned to a closed-loop figure.
  double disturbance_noise = 0.981;

  // Initial uncertainty (position and attitude come from the first mocap fix).
  double initial_velocity_std = 0.5;    ///< [m/s]
  double initial_accel_bias_std = 0.1;  ///< [m/s^2]
  double initial_gyro_bias_std = 0.01;  ///< [rad/s]
  /// Prior std of d at initialisation and at every take-off [m/s^2]: 0.1 g.
  double initial_disturbance_std = 0.981;

  // Robustness.
  double gate_probability = 0.99999;  ///< chi-square gate on the NIS, per measurement dim
  int max_consecutive_gated = 50;     ///< then the measured states' variance is re-inflated
  double max_specific_force = 160.0;  ///< IMU accel norms above are implausible [m/s^2]
  double max_angular_rate = 35.0;     ///< IMU gyro norms above are implausible [rad/s]

  // Health (VehicleEstimate::health, ::valid) and time guards. See docs/estimation.md.
  /// Position std limit [m]; checked only once an absolute position fix (mocap) was fused:
  /// a follower's dead-reckoned position in {m} is not monitored.
  double max_position_std = 0.5;
  double max_velocity_std = 1.0;  ///< velocity std limit [m/s] (initial_velocity_std is below)
  double max_attitude_std = 0.2;  ///< limit for each Euler-angle std [rad]
  /// |pitch| above this is outside the attitude envelope (the Euler-rate matrix is singular
  /// at pi/2; its 1/cos(pitch) is bounded beyond 1.5 rad) [rad], in (0, pi/2).
  double max_pitch = 1.2;
  /// Staleness limit per SensorKind (mocap, imu, optical_flow, compass, battery, relative) [s]:
  /// a monitored kind with no fused measurement for longer makes the estimate invalid.
  /// kInf = not monitored. Battery and relative measurements are not fused by this filter.
  std::array<double, kNumSensorKinds> max_staleness{0.5, 0.25, 0.5, 1.0, kInf, kInf};
  /// true: a kind is monitored only after its first fused measurement (a sensor this vehicle
  /// does not have, e.g. mocap on a follower, is not flagged); false: from initialisation.
  bool stale_after_first_fix = true;
  double max_extrapolation =
      0.5;  ///< Estimate(t) predicts at most this far past the newest event [s]
  /// Events (measurements, commands) stamped further ahead of the newest event are rejected
  /// (kRejectedTimeJump) [s]; `time_jump_reset_count` consecutive ones within this distance of
  /// each other re-anchor the filter at the new time (counted in `time_resets`).
  double max_time_jump = 1.0;
  int time_jump_reset_count = 3;
  double reset_position_std = 1.0;   ///< position std added at a re-anchor [m]
  double reset_attitude_std = 0.05;  ///< attitude std added at a re-anchor [rad]

  // Mode switching (hysteresis: separate thresholds and hold times).
  double takeoff_height = 0.05;        ///< mocap height above ground that signals take-off [m]
  double takeoff_speed = 0.15;         ///< optical-flow speed that signals take-off [m/s]
  double takeoff_accel = 1.5;          ///< |R f - g e3| with the IMU that signals take-off [m/s^2]
  double takeoff_thrust_ratio = 1.1;   ///< command thrust / (m g) that signals take-off [-]
  double takeoff_hold = 0.02;          ///< take-off evidence must persist this long [s]
  double land_height = 0.03;           ///< estimated height above ground below which landing [m]
  double land_speed = 0.1;             ///< estimated speed below which landing is possible [m/s]
  double land_thrust_ratio = kInf;     ///< with a fresh command, thrust / (m g) must be below [-]
  double land_hold = 0.1;              ///< landing evidence must persist this long [s]
  double takeoff_position_std = 0.05;  ///< position std added at take-off [m]
  double takeoff_velocity_std = 0.3;   ///< velocity std added at take-off [m/s]

  /// Throws std::invalid_argument naming the first invalid field.
  void Validate() const;
  /// The replay buffer's entries: buffer_capacity, or when 0 the derived size.
  [[nodiscard]] int BufferCapacity() const;
};

/// Output of VehicleEkf::Estimate.
struct VehicleEstimate {
  /// Initialised and healthy: health.flags == 0 (covariance within its limits, no monitored
  /// kind stale, not extrapolated beyond the limit, finite, pitch inside the envelope).
  bool valid = false;
  EstimateHealth health;  ///< why not valid, staleness per kind, stds
  double time = kNaN;     ///< time of validity [s]
  VehicleMode mode = VehicleMode::kLanded;
  Vec3 position = Vec3::Constant(kNaN);      ///< {n} [m]
  Vec3 position_mpc = Vec3::Constant(kNaN);  ///< {m}: position - start position [m]
  Vec3 velocity = Vec3::Constant(kNaN);      ///< {n} = {m} axes [m/s]
  Vec3 euler = Vec3::Constant(kNaN);         ///< roll, pitch, yaw [rad]
  Vec3 accel_bias = Vec3::Constant(kNaN);    ///< body [m/s^2]
  Vec3 gyro_bias = Vec3::Constant(kNaN);     ///< body [rad/s]
  /// External acceleration d, {n} [m/s^2] (VehicleStateIndex::kDisturbance); 0 while
  /// landed or before a command was fused in flight.
  Vec3 disturbance = Vec3::Constant(kNaN);
  VehicleStateVec x = VehicleStateVec::Constant(kNaN);           ///< full state (VehicleStateIndex)
  VehicleStateCov covariance = VehicleStateCov::Constant(kNaN);  ///< of x
};

/// Multi-modal, multi-rate EKF of the vehicle's own state.
///
/// Inputs: fnmpc::Measurement of kinds mocap (position + Euler), IMU (specific force +
/// rate, body frame), optical flow (world velocity) and compass (yaw), each with its own
/// stamp, in any order within `max_lag`; optional commands (SetCommand) for the command
/// motion model and for take-off/landing evidence. Output: Estimate(t).
/// Modes: landed (p, v held; IMU accel observes roll/pitch and accel bias, gyro the gyro
/// bias) and flying (IMU strapdown or command model); switched with hysteresis.
/// External acceleration d (disturbance observer, offset-free NMPC): flying with the IMU
/// model, every IMU sample with a fresh command is a pseudo-measurement of d,
/// R(euler) (f - b_a) - BodyZ(euler) T s / m = d + noise (the thrust model's error,
/// `command_accel_noise`), fused with attitude and accelerometer bias taken as known, so
/// d stays uncorrelated with the other 15 states, which do not depend on it (the same bits
/// whatever d is); with the command model d enters v' and is observed through the velocity.
/// Reset to 0 at every take-off.
/// Conventions: world {n} ENU z up, ZYX Euler angles, yaw wrapped to (-pi, pi].
/// Initialised by the first mocap fix or by Initialize(). No heap allocation after
/// construction. See docs/estimation.md.
class VehicleEkf {
 public:
  /// Throws std::invalid_argument on an invalid config or vehicle.
  VehicleEkf(const VehicleEkfConfig& config, const model::VehicleParams& vehicle);

  /// Explicit initialisation at time t with position [m] and Euler angles [rad] ({n});
  /// velocity zero, covariance from the mocap noise. Clears the replay buffer.
  void Initialize(double t, const Vec3& position, const Vec3& euler);

  /// Records the command valid from time t [s]: collective thrust [N] and attitude
  /// references [rad]. Used by the command motion model and by the mode logic.
  /// `known_acceleration` [m/s^2, {n}]: the part of the external acceleration the controller
  /// models itself (its wake model, compensation level `wake`), held with the command: the
  /// thrust model then explains it, and d estimates only the rest.
  EkfStatus SetCommand(double t, double thrust, double roll_ref, double pitch_ref, double yaw_ref,
                       const Vec3& known_acceleration = Vec3::Zero());

  /// Fuses one measurement (predicting to its stamp, replaying if it is late).
  EkfStatus Process(const Measurement& m);

  /// State predicted to time t (no change to the filter), with its health. For t before the
  /// last fused stamp, the state at that stamp is returned (time field tells which); for t
  /// beyond it by more than `max_extrapolation`, the state at the limit, flagged
  /// kExtrapolationLimit (never more than max_extrapolation / max_predict_dt sub-steps).
  [[nodiscard]] VehicleEstimate Estimate(double t) const;

  /// Current mode (after the newest event).
  [[nodiscard]] VehicleMode mode() const { return s_.mode; }
  /// True once initialised.
  [[nodiscard]] bool initialized() const { return s_.initialized; }
  /// Stamp of the newest fused event [s].
  [[nodiscard]] double time() const { return s_.time; }
  /// Start position: origin of the MPC inertial frame {m} [m] (NaN before initialisation).
  [[nodiscard]] const Vec3& mpc_origin() const { return s_.origin; }
  /// Rejection / acceptance counters (a copy, cheap).
  [[nodiscard]] EkfCounters counters() const;
  /// Configuration in use.
  [[nodiscard]] const VehicleEkfConfig& config() const { return config_; }
  /// Changes with every call that may change the filter (Initialize, SetCommand, Process):
  /// two Estimate(t) calls at the same t and revision return the same estimate.
  [[nodiscard]] std::uint64_t revision() const { return revision_; }

 private:
  struct Command {
    double thrust = kNaN, roll = kNaN, pitch = kNaN, yaw = kNaN;
    Vec3 known_acceleration = Vec3::Zero();  // [m/s^2, {n}], see SetCommand
  };
  struct Event {
    double stamp = kNaN;
    int order = 0;
    bool is_command = false;
    Command command;
    Measurement m;
  };
  struct State {
    double time = kNaN;
    bool initialized = false;
    VehicleStateVec x = VehicleStateVec::Zero();
    VehicleStateCov P = VehicleStateCov::Identity();
    VehicleMode mode = VehicleMode::kLanded;
    Vec3 imu_accel = Vec3::Zero();
    Vec3 imu_gyro = Vec3::Zero();
    double imu_stamp = kNaN;
    Command command;
    double command_stamp = kNaN;
    double ground_z = 0.0;
    Vec3 origin = Vec3::Constant(kNaN);
    std::array<bool, 4> takeoff_evidence{};  // mocap height, flow speed, imu accel, thrust
    double takeoff_since = kNaN;
    double land_since = kNaN;
    std::array<int, kNumSensorKinds> consecutive_gated{};
    std::int64_t gate_resets = 0;
    std::int64_t mode_switches = 0;
    // Stamp of the newest fused (or, for the IMU, used) measurement per kind; NaN = none.
    std::array<double, kNumSensorKinds> last_fused{kNaN, kNaN, kNaN, kNaN, kNaN, kNaN};
  };

  EkfStatus Apply(const Event& e, State* s) const;
  EkfStatus ApplyMeasurement(const Measurement& m, State* s) const;
  void Predict(double t, State* s) const;
  void PredictStep(double dt, State* s) const;
  void InitState(double t, const Vec3& position, const Vec3& euler, State* s) const;
  void UpdateTakeoffEvidence(int index, bool evidence, double t, State* s) const;
  void CheckLanding(double t, State* s) const;
  void SwitchMode(VehicleMode mode, State* s) const;
  void ResetDisturbance(State* s) const;
  void UpdateDisturbance(const Measurement& m, State* s) const;
  template <int M>
  EkfStatus Update(SensorKind kind, const Vec<M>& y, const Mat<M, VehicleStateIndex::kSize>& H,
                   const Mat<M, M>& R, State* s) const;
  [[nodiscard]] bool CommandFresh(double t, const State& s) const;
  // True when an event stamped t must be rejected as a forward time jump; re-anchors the
  // filter at t after `time_jump_reset_count` consistent jumps (and then returns false).
  bool TimeJumpRejected(double t);
  void FillHealth(const State& st, double t_query, EstimateHealth* h) const;

  VehicleEkfConfig config_;
  model::VehicleParams vehicle_;
  std::array<double, 7> gate_{};  // chi-square gate per measurement dimension 1..6
  State s_;
  std::uint64_t revision_ = 0;
  ReplayBuffer<Event, State> buffer_;
  EkfCounters counters_;
  TimeJumpGuard time_jump_;
};

/// Continuous-time IMU-driven flying model f(x, accel, gyro) (VehicleStateIndex layout).
VehicleStateVec ImuFlow(const VehicleStateVec& x, const Vec3& accel, const Vec3& gyro);
/// Jacobian d ImuFlow / dx.
VehicleStateCov ImuFlowJacobian(const VehicleStateVec& x, const Vec3& accel, const Vec3& gyro);
/// Continuous-time command-driven flying model; thrust [N], refs (roll, pitch, yaw) [rad].
VehicleStateVec CommandFlow(const VehicleStateVec& x, double thrust, const Vec3& refs,
                            const model::VehicleParams& vehicle);
/// Jacobian d CommandFlow / dx.
VehicleStateCov CommandFlowJacobian(const VehicleStateVec& x, double thrust, const Vec3& refs,
                                    const model::VehicleParams& vehicle);
/// Acceleration the thrust model leaves unexplained: R(euler) (accel - b_a) - BodyZ(euler)
/// thrust s / m [m/s^2, {n}] (gravity cancels), the IMU pseudo-measurement of the external
/// acceleration d; accel [m/s^2] body frame, thrust [N] the command.
Vec3 UnexplainedAcceleration(const VehicleStateVec& x, const Vec3& accel, double thrust,
                             const model::VehicleParams& vehicle);
/// Landed accelerometer model: specific force of a vehicle at rest, R' g e3 + b_a [m/s^2].
Vec3 LandedAccel(const VehicleStateVec& x);
/// Jacobian d LandedAccel / dx.
Mat<3, VehicleStateIndex::kSize> LandedAccelJacobian(const VehicleStateVec& x);

}  // namespace fnmpc::estimation

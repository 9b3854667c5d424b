// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/estimation/ekf_math.hpp"
#include "fnmpc/estimation/ekf_types.hpp"
#include "fnmpc/estimation/replay_buffer.hpp"

namespace fnmpc::estimation {

/// Per-neighbour state layout shared with the follower NMPC (8 entries), MPC frame {m}
/// (axes of {n}, origin at the observer's start position):
///   dx  = p_neighbour - p_self [m] (3), v_j neighbour velocity [m/s] (3),
///   psi_j neighbour yaw [rad], wz_j neighbour yaw rate [rad/s].
/// Constant-velocity dynamics: dx' = v_j - v_self, v_j' = 0, psi_j' = wz_j, wz_j' = 0.
struct NeighbourStateIndex {
  static constexpr int kRelPos = 0;   ///< dx [m], 3
  static constexpr int kVel = 3;      ///< v_j [m/s], 3
  static constexpr int kYaw = 6;      ///< psi_j [rad]
  static constexpr int kYawRate = 7;  ///< wz_j [rad/s]
  static constexpr int kSize = 8;
};
using NeighbourStateVec = Vec<NeighbourStateIndex::kSize>;
using NeighbourStateCov = Mat<NeighbourStateIndex::kSize, NeighbourStateIndex::kSize>;

/// How NeighbourEkf fuses a relative observation.
enum class RelativeUpdate : int {
  /// The observation is converted to a relative position in {m} (and the neighbour's yaw)
  /// with the linearised covariance of the conversion; the update is linear (H = I). No
  /// singularity: well defined straight above or below (see docs/estimation.md).
  kCartesian = 0,
  /// Legacy: EKF update in (range, bearing, elevation, relative yaw). The bearing Jacobian
  /// grows as 1 / horizontal distance: diverges with a neighbour straight above or below.
  kSpherical = 1,
};

/// Settings of NeighbourEkf. Measurement noise comes from `sensors.relative` (range std
/// noise[0] * (1 + range_noise_growth * range), bearing noise[1], elevation noise[2],
/// relative yaw noise2[0]).
struct NeighbourEkfConfig {
  SensorsConfig sensors;  ///< noise source (simulator defaults unless overridden)
  int observer = -1;      ///< accept only measurements taken by this vehicle; -1 = any
  int target = -1;        ///< accept only observations of this neighbour; -1 = any
  double max_lag = 0.3;   ///< replay window [s]
  /// Replay buffer entries (measurements + own-velocity samples); 0: ReplayCapacity of
  /// max_lag for the relative sensor's rate and own_velocity_rate_hz (what the window holds).
  int buffer_capacity = 0;
  double own_velocity_rate_hz = 20.0;  ///< rate of PredictTo calls (the control rate) [Hz]
  /// Neighbour acceleration white noise [m/s^2/sqrt(Hz)]; with hover_accel_noise > 0 that of
  /// the manoeuvring mode.
  double accel_noise = 0.5;
  /// Interacting multiple model (Blom and Bar-Shalom 1988; Bar-Shalom, Li, Kirubarajan 2001,
  /// sec. 11.6): a second constant-velocity model for a neighbour holding its position, with
  /// this acceleration white noise [m/s^2/sqrt(Hz)]; the two models are mixed by their
  /// measurement likelihoods. 0: one model (accel_noise only). See docs/estimation.md.
  double hover_accel_noise = 0.05;
  double hover_sojourn = 5.0;      ///< mean time in the hover mode [s] (mode switching)
  double manoeuvre_sojourn = 5.0;  ///< mean time in the manoeuvring mode [s]
  double yaw_accel_noise = 0.3;    ///< neighbour yaw acceleration white noise [rad/s^2/sqrt(Hz)]
  /// White-noise density of the own velocity input's error integrated into dx [m/sqrt(s)]:
  /// the own estimator's velocity error, which the prediction dx' = v_j - v_self carries.
  /// 0.007: its largest density over 0.05-1 s, measured against the simulator's truth
  /// (docs/estimation.md, "Own velocity"). 0 = the own velocity is taken as exact.
  double own_velocity_noise = 0.007;
  double initial_velocity_std = 1.0;  ///< neighbour velocity std at initialisation [m/s]
  double initial_yaw_rate_std = 0.5;  ///< neighbour yaw rate std at initialisation [rad/s]
  double gate_probability = 0.99999;  ///< chi-square gate on the 4-dim NIS
  int max_consecutive_gated = 50;     ///< then re-initialised from the measurement
  RelativeUpdate relative_update = RelativeUpdate::kCartesian;  ///< measurement model

  // Health (NeighbourEstimate::health, ::valid) and time guards. See docs/estimation.md.
  double max_position_std = 0.5;   ///< dx std limit, largest axis [m]; kInf = off
  double max_velocity_std = 2.0;   ///< v_j std limit [m/s] (above initial_velocity_std)
  double max_yaw_std = 0.5;        ///< psi_j std limit [rad]
  double max_staleness = 0.5;      ///< no accepted relative measurement for longer: stale [s]
  double max_extrapolation = 0.5;  ///< StateAt / EstimateAt predict at most this far ahead [s]
  /// Events stamped further ahead of the newest event are rejected (kRejectedTimeJump) [s];
  /// `time_jump_reset_count` consecutive ones within this distance of each other make the
  /// filter forget the neighbour (re-initialised by the next measurement; `time_resets`).
  double max_time_jump = 1.0;
  int time_jump_reset_count = 3;

  /// Throws std::invalid_argument naming the first invalid field.
  void Validate() const;
  /// The replay buffer's entries: buffer_capacity, or when 0 the derived size.
  [[nodiscard]] int BufferCapacity() const;
};

/// Relative measurement model h(dx, psi_j; own euler) = (range, bearing, elevation,
/// relative yaw) of core/sensors.hpp, for the NeighbourStateIndex layout.
Vec<4> RelativeMeasurementModel(const NeighbourStateVec& x, const Vec3& own_euler);
/// Jacobian of RelativeMeasurementModel with respect to x (4 x 8).
Mat<4, NeighbourStateIndex::kSize> RelativeMeasurementJacobian(const NeighbourStateVec& x,
                                                               const Vec3& own_euler);
/// Jacobian of RelativeMeasurementModel with respect to the own Euler angles (4 x 3).
Mat<4, 3> RelativeMeasurementOwnAttitudeJacobian(const NeighbourStateVec& x, const Vec3& own_euler);

/// Relative observation converted to z = (p_neighbour - p_self in {m} [m], neighbour yaw
/// [rad]) with its covariance R: linearised (range, bearing, elevation, relative yaw)
/// noise of `spec` (range std noise[0] * (1 + range_noise_growth * range)), the
/// second-order bearing-elevation term r^2 sigma_b^2 sigma_e^2 sin^2(el) along the azimuth
/// direction (keeps R positive definite at elevation +-90 deg), and the own-attitude
/// covariance `own_euler_cov` [rad^2] mapped through the rotation.
void RelativeToCartesian(const RelativeObservation& o, const Vec3& own_euler,
                         const Mat3& own_euler_cov, const SensorSpec& spec, Vec<4>* z,
                         Mat<4, 4>* R);

/// Output of NeighbourEkf::EstimateAt.
struct NeighbourEstimate {
  /// Initialised and healthy: health.flags == 0 (dx, v_j and yaw stds within their limits,
  /// a relative measurement within max_staleness, not extrapolated beyond the limit, finite).
  bool valid = false;
  EstimateHealth health;  ///< reasons; staleness[kRelative]; position_std is that of dx
  double time = kNaN;     ///< time of validity of x [s]
  NeighbourStateVec x = NeighbourStateVec::Constant(kNaN);           ///< NeighbourStateIndex
  NeighbourStateCov covariance = NeighbourStateCov::Constant(kNaN);  ///< of x
};

/// EKF of one neighbour from relative range, bearing, elevation and relative yaw.
///
/// Inputs: kRelative measurements with the observer's own Euler angles [rad] (and
/// optionally their covariance) and own velocity in {m} [m/s] at the measurement stamp;
/// own-velocity samples through PredictTo. Between events dx integrates v_j minus the
/// trapezoidal average of the own velocity. Late and out-of-order events within
/// `max_lag` are replayed exactly. Initialised by the first valid measurement (velocity
/// 0, yaw rate 0 with the configured std). Output: state() in NeighbourStateIndex layout,
/// ready for the follower NMPC. No heap allocation after construction.
class NeighbourEkf {
 public:
  /// Throws std::invalid_argument on an invalid config.
  explicit NeighbourEkf(const NeighbourEkfConfig& config);

  /// Fuses one kRelative measurement. own_euler: observer roll, pitch, yaw [rad];
  /// own_velocity: observer velocity in {m} [m/s]; own_euler_cov: optional 3x3 covariance
  /// of own_euler [rad^2] added to the measurement noise.
  EkfStatus Process(const Measurement& relative, const Vec3& own_euler, const Vec3& own_velocity,
                    const Mat3* own_euler_cov = nullptr);

  /// Advances the filter to time t [s] with the own velocity at t [m/s] (the own velocity
  /// is interpolated linearly since the previous event). Returns kRejectedTooOld or
  /// kRejectedNonFinite when the sample cannot be used.
  EkfStatus PredictTo(double t, const Vec3& own_velocity);

  /// State at the newest event (NeighbourStateIndex layout); NaN before initialisation.
  [[nodiscard]] NeighbourStateVec state() const;
  /// Covariance of state().
  [[nodiscard]] const NeighbourStateCov& covariance() const { return s_.P; }
  /// State predicted to t with the own velocity held at own_velocity (no filter change);
  /// at most `max_extrapolation` past the newest event (EstimateAt tells when capped).
  [[nodiscard]] NeighbourStateVec StateAt(double t, const Vec3& own_velocity) const;
  /// State and covariance predicted as StateAt, with their health (valid, reasons).
  [[nodiscard]] NeighbourEstimate EstimateAt(double t, const Vec3& own_velocity) const;
  /// Stamp of the newest event [s].
  [[nodiscard]] double time() const { return s_.time; }
  /// True once a measurement initialised the filter.
  [[nodiscard]] bool initialized() const { return s_.initialized; }
  /// Rejection / acceptance counters (a copy, cheap).
  [[nodiscard]] EkfCounters counters() const;
  /// Configuration in use.
  [[nodiscard]] const NeighbourEkfConfig& config() const { return config_; }
  /// Probability of the hover mode (interacting multiple model); NaN when it is off or before
  /// initialisation.
  [[nodiscard]] double hover_probability() const;
  /// Replay buffer entries (fixed at construction).
  [[nodiscard]] int buffer_capacity() const { return buffer_.capacity(); }
  /// Forgets the tracked vehicle and tracks `target` instead (observations of other targets
  /// are rejected from now on): state, buffer and time guard as after construction; the
  /// counters keep counting. No heap allocation (a tracking slot's reuse).
  void Retarget(int target);

 private:
  struct Event {
    double stamp = kNaN;
    int order = 0;  // 0: own-velocity sample, 1: measurement
    Measurement m;
    Vec3 own_euler = Vec3::Zero();
    Vec3 own_velocity = Vec3::Zero();
    Mat3 own_euler_cov = Mat3::Zero();
  };
  // One motion model of the interacting multiple model: its estimate and covariance.
  struct Mode {
    NeighbourStateVec x = NeighbourStateVec::Zero();
    NeighbourStateCov P = NeighbourStateCov::Identity();
  };
  static constexpr int kHover = 0, kManoeuvre = 1, kModes = 2;
  struct State {
    double time = kNaN;
    bool initialized = false;
    // The estimate: with the multiple model the probability-weighted mix of the modes.
    NeighbourStateVec x = NeighbourStateVec::Zero();
    NeighbourStateCov P = NeighbourStateCov::Identity();
    std::array<Mode, kModes> mode{};
    Vec<kModes> mu = Vec<kModes>::Zero();      // mode probabilities
    Vec3 own_velocity = Vec3::Constant(kNaN);  // own velocity at `time`
    int consecutive_gated = 0;
    std::int64_t gate_resets = 0;
    double last_fused = kNaN;  // stamp of the newest accepted measurement
  };

  EkfStatus Apply(const Event& e, State* s) const;
  void Predict(double t, const Vec3& own_velocity, State* s) const;
  void InitFromMeasurement(const Event& e, State* s) const;
  [[nodiscard]] Mat<4, 4> NoiseCovariance(const Event& e, const NeighbourStateVec& x) const;
  EkfStatus UpdateSpherical(const Event& e, const Mode& prior, Mode* m, UpdateResult* r) const;
  /// z, R: the event's measurement as a relative position and yaw (RelativeToCartesian),
  /// the same for every mode.
  EkfStatus UpdateCartesian(const Vec<4>& z, const Mat<4, 4>& R, const Mode& prior, Mode* m,
                            UpdateResult* r) const;
  // The update of every mode, the mode probabilities from their likelihoods.
  EkfStatus Update(const Event& e, State* s) const;
  // The process noise of one mode over h [s].
  [[nodiscard]] NeighbourStateCov ProcessNoise(double h, double accel_noise) const;
  // s->x, s->P from the modes (the moment-matched mix).
  static void Combine(State* s);
  [[nodiscard]] bool multiple_model() const { return config_.hover_accel_noise > 0.0; }
  // Predicts a copy to t (capped at max_extrapolation); *capped tells whether it was.
  State PredictedCopy(double t, const Vec3& own_velocity, bool* capped) const;
  // See VehicleEkf::TimeJumpRejected; the re-anchor forgets the neighbour.
  bool TimeJumpRejected(double t);

  NeighbourEkfConfig config_;
  double gate_ = 0.0;
  State s_;
  ReplayBuffer<Event, State> buffer_;
  EkfCounters counters_;
  TimeJumpGuard time_jump_;
};

}  // namespace fnmpc::estimation

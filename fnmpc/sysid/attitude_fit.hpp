// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <string>
#include <vector>

#include "fnmpc/core/types.hpp"

namespace fnmpc::sysid {

/// First-order closed-loop attitude model of one axis with a transport delay d and an
/// offset c: y'(t) = (k r(t - d) + c - y(t)) / tau, y(t0) = y0, the reference r held between
/// samples. The offset is a steady attitude bias (c = k b for an autopilot tracking
/// k (r + b)): without it a biased vehicle's offset would be absorbed into k and y0.
struct FirstOrderFit {
  double time_constant = 0.0;  ///< tau of the model with delay [s]
  double delay = 0.0;          ///< d [s]
  double gain = 0.0;           ///< k [-]
  double initial = 0.0;        ///< y0 [rad]
  double offset = 0.0;         ///< c [rad]
  /// tau + d [s]: the delay-free first-order model with the same mean residence time (area
  /// above the normalised step response). This is what the NMPC prediction model uses.
  double equivalent_time_constant = 0.0;
  double rms = 0.0;          ///< RMS residual [rad]
  double noise_sigma = 0.0;  ///< robust noise estimate of the measured angle [rad]
  /// Standard errors of time_constant, gain, delay, initial, offset (Gauss-Newton
  /// covariance).
  std::array<double, 5> std_error{};
  bool delay_at_bound = false;  ///< the delay ended on a bound of its range
  double r_squared = 0.0;       ///< 1 - SS_res / SS_tot of the measured angle
};

/// Per-sample mask: a non-zero entry marks a sample that enters a fit (empty: all).
using SampleMask = std::vector<unsigned char>;

/// Settings of FitFirstOrder.
struct FirstOrderFitSettings {
  bool fit_delay = true;   ///< false: d = 0
  double max_delay = 0.1;  ///< upper bound of d [s]
  SampleMask use;          ///< samples that enter the fit (empty: all)
};

/// Missing samples in a log: the interval between two consecutive time stamps that are
/// further apart than `factor` times the median sampling interval.
struct Gap {
  double start = 0.0;     ///< time of the last sample before the gap [s]
  double end = 0.0;       ///< time of the first sample after it [s]
  std::size_t index = 0;  ///< index of the first sample after it
};

/// The gaps of the increasing time stamps `t` (steps > factor x the median step). Throws
/// std::invalid_argument when factor <= 1.
std::vector<Gap> FindGaps(const std::vector<double>& t, double factor);

/// Mask of the samples not affected by the gaps: a sample at t_i in (start, end + settle]
/// of a gap is left out, because what the reference did inside the gap is unknown and the
/// response after it depends on it until the loop has settled.
SampleMask GapMask(const std::vector<double>& t, const std::vector<Gap>& gaps, double settle);

/// "Fit" of a prediction in percent (normalised RMS error): 100 (1 - |y - yhat| / |y -
/// mean(y)|) over the samples with use[i] != 0 (empty: all); 100 is a perfect fit, 0 no
/// better than the mean, negative worse. NaN when no sample is used.
double FitPercent(const std::vector<double>& measured, const std::vector<double>& predicted,
                  const SampleMask& use = {});

/// Exact response of the first-order model with delay and offset at the sample times `t`
/// (increasing), for the reference samples `ref` (held constant until the next sample) [rad].
template <class T>
void SimulateFirstOrder(const std::vector<double>& t, const std::vector<double>& ref, const T& tau,
                        const T& gain, const T& offset, const T& delay, const T& y0,
                        std::vector<T>* y);

/// Fits (tau, k, d, y0, c) with Ceres (Levenberg-Marquardt, Huber loss of 3 noise sigma on
/// every sample). Starts from a grid over tau with k, y0 by linear least squares. Throws
/// std::invalid_argument on mismatched sizes, fewer than 20 samples or a constant reference.
FirstOrderFit FitFirstOrder(const std::vector<double>& t, const std::vector<double>& ref,
                            const std::vector<double>& angle,
                            const FirstOrderFitSettings& settings = {});

/// Light-weight model of the simulator's attitude loop for one axis (docs/simulator.md):
/// every 1/autopilot_rate_hz the PD law commands the angular acceleration
/// a_c = clamp(K_p (k r - y) - K_d w, +-max_angular_acceleration), the motors deliver it with
/// a first-order lag (motor_time_constant), and y'' = a is integrated with semi-implicit Euler
/// at physics_dt (MuJoCo's Euler). Inertia cancels because the gains are normalised by it.
struct AttitudeLoopSettings {
  double physics_dt = 0.001;               ///< [s]
  double autopilot_rate_hz = 250.0;        ///< [Hz]
  double motor_time_constant = 0.02;       ///< [s]
  double max_angular_acceleration = kInf;  ///< actuator limit [rad/s^2] (yaw: T_q/T_k m g / I_z)
  double delay = 0.0;  ///< transport delay of the reference [s] (the loop sees r(t - delay))
};

/// Response of the light-weight loop at the sample times `t` from rest at y0 [rad]; the
/// loop's set point is gain * ref (add offset / gain to ref for an offset).
template <class T>
void SimulateAttitudeLoop(const std::vector<double>& t, const std::vector<double>& ref, double gain,
                          const T& kp, const T& kd, double y0, const AttitudeLoopSettings& settings,
                          std::vector<T>* y);

/// Fitted lumped PD gains of one axis.
struct PdFit {
  double kp = 0.0;            ///< [1/s^2]
  double kd = 0.0;            ///< [1/s]
  double delay = 0.0;         ///< transport delay of the reference [s] (on the physics_dt grid)
  double kp_std_error = 0.0;  ///< standard error of kp (Gauss-Newton covariance) [1/s^2]
  double kd_std_error = 0.0;  ///< standard error of kd [1/s]
  bool at_bound = false;      ///< a gain ended on a bound of its range
  double rms = 0.0;           ///< RMS residual against the measured angle [rad]
  double r_squared = 0.0;     ///< 1 - SS_res / SS_tot of the measured angle
  /// RMS difference between the light-weight loop and the identified first-order
  /// response (with its delay) [rad].
  double rms_to_first_order = 0.0;
};

/// Fits K_p, K_d and a transport delay d of the reference by simulating the light-weight
/// loop (gain k and start from `first_order`) against the measured angle. The start is the
/// best point of a grid over d (0 to the first-order delay, physics_dt steps) and K_p (log
/// grid) with K_d = (tau_eq - d) K_p, i.e. on the valley of responses with the identified
/// mean residence time. The gains are fitted in log coordinates (positive, scaled), bounded,
/// and a simulation that diverges is rejected, never handed to Ceres; d is refined by a
/// line search on the physics_dt grid. Throws std::invalid_argument when no grid point
/// gives a finite simulation or the fit fails.
PdFit FitPdGains(const std::vector<double>& t, const std::vector<double>& ref,
                 const std::vector<double>& angle, const FirstOrderFit& first_order,
                 const AttitudeLoopSettings& settings, const SampleMask& use = {});

/// Response of the fitted PD loop (gain, offset and start from `first_order`) at `t`.
std::vector<double> SimulatePdFit(const std::vector<double>& t, const std::vector<double>& ref,
                                  const FirstOrderFit& first_order, const PdFit& pd,
                                  const AttitudeLoopSettings& settings);

/// Response of the fitted first-order model at `t`.
std::vector<double> SimulateFirstOrderFit(const std::vector<double>& t,
                                          const std::vector<double>& ref,
                                          const FirstOrderFit& first_order);

/// Two folds of held-out segments: the record is cut at the changes of the reference into
/// segments of at least `min_segment` seconds (shorter ones are merged with the next), and
/// alternate segments form fold 0 and fold 1. The first segment is fold 2: it is in the
/// training data of both folds (it fixes the start y0 of the simulated response, which a
/// fit without the record's start could not determine) and never held out. Returns the
/// fold of every sample (0, 1 or 2).
std::vector<unsigned char> SegmentFolds(const std::vector<double>& t,
                                        const std::vector<double>& ref, double min_segment,
                                        int* segments = nullptr);

/// Cross-validation of the two attitude model structures on held-out segments: each model
/// is fitted on one fold (samples of `use` only) and predicts the other, in both directions.
struct HeldOutValidation {
  std::vector<unsigned char> fold;        ///< fold of every sample (0/1)
  int segments = 0;                       ///< number of segments
  std::vector<double> first_order;        ///< held-out prediction of each sample, first order
  std::vector<double> pd_loop;            ///< same, PD loop (NaN where its fit failed)
  double first_order_rms = kNaN;          ///< RMS of the held-out predictions [rad]
  double pd_rms = kNaN;                   ///< same, PD loop [rad]
  double first_order_fit_percent = kNaN;  ///< FitPercent of the held-out predictions
  double pd_fit_percent = kNaN;           ///< same, PD loop
  /// Relative held-out RMS difference (PD - first order) / min of the two, per fold
  /// (predicting fold 0 and fold 1) and pooled; > 0: the first-order model predicts better.
  std::array<double, 2> fold_margin{kNaN, kNaN};
  double margin = kNaN;
  std::string pd_error;  ///< why the PD loop could not be fitted on a fold (empty: it could)
};

/// Runs the cross-validation (FitFirstOrder and FitPdGains with `loop` on each fold).
HeldOutValidation ValidateOnHeldOutSegments(const std::vector<double>& t,
                                            const std::vector<double>& ref,
                                            const std::vector<double>& angle, const SampleMask& use,
                                            const AttitudeLoopSettings& loop, double min_segment);

}  // namespace fnmpc::sysid

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/model/quadrotor_model.hpp"
#include "fnmpc/model/vehicle_params.hpp"

namespace fnmpc::sysid {

/// A logged closed-loop flight (docs/data-formats.md, flight.csv); all vectors have the
/// same length and t is increasing.
struct FlightLog {
  std::vector<double> t;        ///< [s]
  std::vector<Vec<9>> state;    ///< x y z [m], vx vy vz [m/s], roll pitch yaw [rad] (measured)
  std::vector<Vec<4>> command;  ///< thrust [N] (whole vehicle), roll, pitch, yaw [rad]
  std::vector<double> voltage;  ///< battery voltage [V] (informative only)
};

/// Settings of the windowed open-loop prediction error.
struct CalibrationSettings {
  double window = 1.0;           ///< prediction window length [s]
  double window_stride = 0.5;    ///< start-to-start distance of windows [s]
  int substeps = 2;              ///< RK4 steps per log interval
  double position_scale = 0.01;  ///< position residuals are divided by this [m]
  double angle_scale = 0.005;    ///< roll/pitch residuals are divided by this [rad]
  int bootstrap = 0;             ///< bootstrap refits over resampled windows (0: none)
  unsigned bootstrap_seed = 1;   ///< seed of the window resampling
};

/// One open-loop prediction: from the logged state at `start`, driven by the logged
/// commands (held between samples) through the NMPC prediction model with bias.
struct WindowPrediction {
  int start = 0;              ///< index of the first sample in the log
  std::vector<Vec<9>> state;  ///< predicted state at samples start, start + 1, ...
};

/// Result of Calibrate.
struct CalibrationResult {
  model::CalibrationBias bias;  ///< estimated biases
  double position_error_before =
      0.0;  ///< mean |p_logged - p_predicted| over windows, input bias [m]
  double position_error_after = 0.0;  ///< the same with the estimated bias [m]
  int windows = 0;                    ///< windows used
  bool converged = false;             ///< Ceres reported a usable solution
  /// Standard errors of (roll, pitch, thrust scale) from the Ceres covariance, scaled by
  /// the residual variance; NaN when it is not computable. The window residuals are
  /// correlated in time, so these are optimistic (a lower bound).
  std::array<double, 3> std_error{kNaN, kNaN, kNaN};
  /// Standard deviations of (roll, pitch, thrust scale) over `bootstrap` refits on windows
  /// resampled with replacement (keeps the correlation within a window); NaN without.
  std::array<double, 3> bootstrap_std_error{kNaN, kNaN, kNaN};
  bool at_bound = false;    ///< an estimate ended on its bound (+-0.5 rad, [0.5, 2])
  double rms_scaled = 0.0;  ///< RMS of the scaled residuals at the solution [-]
};

/// One step of the NMPC prediction model with bias: the attitude tracks k (cmd + bias),
/// the thrust is scale * cmd (QuadrotorModel::Flow with u = [scale T, roll + b_r,
/// pitch + b_p]); RK4 over dt [s] in `substeps` steps. Templated for automatic
/// differentiation (T = double or ceres::Jet).
template <class T>
Eigen::Matrix<T, 9, 1> PredictStep(const Eigen::Matrix<T, 9, 1>& x, const Vec<4>& command,
                                   const T& bias_roll, const T& bias_pitch, const T& thrust_scale,
                                   const model::AttitudeModelParams& m, double dt, int substeps);

/// Window start indices for `log` under `settings` (windows that fit inside the log).
std::vector<int> WindowStarts(const FlightLog& log, const CalibrationSettings& settings);

/// Predicts every window with `params` (its mass, attitude model and bias).
std::vector<WindowPrediction> PredictWindows(const model::VehicleParams& params,
                                             const FlightLog& log,
                                             const CalibrationSettings& settings = {});

/// Mean position error [m] of the predictions against the log (all window samples).
double MeanPositionError(const FlightLog& log, const std::vector<WindowPrediction>& windows);

/// Estimates roll/pitch bias and thrust scale so that the model's windowed open-loop
/// predictions match the log (Ceres, automatic derivatives, position and roll/pitch
/// residuals). `params` gives mass and the attitude model; its bias is the "before" case
/// and the start. Throws std::invalid_argument on inconsistent sizes, non-increasing time or
/// a log shorter than one window.
CalibrationResult Calibrate(const model::VehicleParams& params, const FlightLog& log,
                            const CalibrationSettings& settings = {});

}  // namespace fnmpc::sysid

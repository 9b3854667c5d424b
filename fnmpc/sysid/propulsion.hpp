// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <vector>

#include "fnmpc/model/vehicle_params.hpp"

/// System identification: logs in, fitted vehicle parameters out. Pure algorithms (no files).
namespace fnmpc::sysid {

/// One propeller and motor on a thrust stand; all vectors have the same length.
struct BenchData {
  std::vector<double> throttle;  ///< ESC throttle in [0, 1]
  std::vector<double> voltage;   ///< battery voltage [V]
  std::vector<double> rpm;       ///< rotor speed [rpm]
  std::vector<double> thrust;    ///< thrust of the rotor [N]
  std::vector<double> torque;    ///< reaction torque of the rotor [N m]
};

/// Result of FitPropulsion.
struct PropulsionFit {
  double thrust_constant = 0.0;            ///< T_k [N / rpm^2], thrust = T_k rpm^2
  double torque_constant = 0.0;            ///< T_q [N m / rpm^2], torque = T_q rpm^2
  model::ThrottlePolynomial throttle;      ///< throttle = sum c(i,j) f^i V^j, i + j <= 3
  double thrust_constant_std_error = 0.0;  ///< standard error of T_k [N / rpm^2]
  double torque_constant_std_error = 0.0;  ///< standard error of T_q [N m / rpm^2]
  double thrust_rms = 0.0;                 ///< RMS residual of thrust = T_k rpm^2 [N]
  double torque_rms = 0.0;                 ///< RMS residual of torque = T_q rpm^2 [N m]
  double throttle_rms = 0.0;               ///< RMS residual of the polynomial [-]
  double throttle_max_abs = 0.0;           ///< largest |residual| of the polynomial [-]
  /// Largest |residual| of the polynomial at thrusts of at least 20 % of the bench's
  /// largest (the flight envelope; near idle a cubic cannot follow every motor map) [-]
  double throttle_max_abs_envelope = 0.0;
  int samples = 0;             ///< samples used for the constants
  int polynomial_samples = 0;  ///< samples used for the polynomial (thrust > 0)
};

/// Least squares on the thrust-stand samples: T_k and T_q through the origin in rpm^2,
/// and the 10 coefficients of the cubic thrust-throttle-voltage polynomial (samples with
/// zero thrust, i.e. below idle, are left out of the polynomial). Throws
/// std::invalid_argument on mismatched sizes, fewer than 10 usable samples, or a
/// rank-deficient design (e.g. a single voltage).
PropulsionFit FitPropulsion(const BenchData& bench);

}  // namespace fnmpc::sysid

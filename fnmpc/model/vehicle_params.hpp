// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/eigen_abi.hpp"
#include <array>
#include <string>

namespace fnmpc::model {

/// Thrust-throttle-voltage characteristic of one rotor:
/// throttle = sum_{i+j<=3} c(i, j) * f^i * V^j, with f the thrust of one rotor [N]
/// and V the battery voltage [V]. Entries with i + j > 3 are zero.
struct ThrottlePolynomial {
  Eigen::Matrix4d c = Eigen::Matrix4d::Zero();  ///< c(i, j) multiplies f^i V^j

  /// Throttle in [0, 1] nominally (not clamped here) for one rotor's thrust f [N] at voltage V.
  [[nodiscard]] double Throttle(double f, double voltage) const;
  /// d throttle / d f at (f, V).
  [[nodiscard]] double DThrottleDThrust(double f, double voltage) const;
  /// Inverse in f for a given throttle and voltage (Newton on the monotone branch, started
  /// from f_guess); returns NaN when no thrust in [0, f_max] gives that throttle.
  [[nodiscard]] double Thrust(double throttle, double voltage, double f_max = 50.0) const;
};

/// Calibration biases (written by `fnmpc calibrate`): the attitude loop tracks
/// (commanded angle + bias) and the vehicle produces thrust_scale * commanded thrust.
struct CalibrationBias {
  double roll = 0.0;          ///< [rad]
  double pitch = 0.0;         ///< [rad]
  double thrust_scale = 1.0;  ///< [-]
};

/// Physical and identified parameters of one quadrotor (the vehicle YAML of
/// docs/data-formats.md). Roll, pitch, yaw order in every 3-vector.
struct VehicleParams {
  double mass = 1.37;                                          ///< [kg]
  Eigen::Vector3d inertia{0.0123, 0.0136, 0.0107};             ///< body principal inertia [kg m^2]
  double thrust_constant = 9.803e-8;                           ///< T_k [N / rpm^2]
  double torque_constant = 1.507e-9;                           ///< T_q [N m / rpm^2]
  ThrottlePolynomial throttle;                                 ///< thrust-throttle-voltage map
  Eigen::Vector3d attitude_time_constant{0.1203, 0.1303, 0.0651};  ///< tau_i [s]
  Eigen::Vector3d attitude_gain{1.01, 1.02, 0.99};             ///< k_i [-]
  Eigen::Vector3d attitude_kp{3.0, 3.0, 0.5};  ///< lumped PD proportional gains (see docs/simulator.md)
  Eigen::Vector3d attitude_kd{0.4, 0.4, 0.4};  ///< lumped PD derivative gains (see docs/simulator.md)
  double arm_length = 0.225;                   ///< motor axis to centre [m]
  CalibrationBias bias;                        ///< identity unless calibrated
  bool has_bias = false;                       ///< true when the file carried a `bias` block

  /// Throws std::invalid_argument naming the field when a value is not physical (an inertia
  /// that is not RealisableInertia among them).
  void Validate() const;
};

/// Why principal moments of inertia [kg m^2] belong to no rigid body, or "" when they do: each
/// must be finite and > 0 (positive definite) and none may exceed the sum of the other two
/// (triangle inequality: Ixx + Iyy >= Izz and its permutations; MuJoCo refuses such a body).
std::string UnrealisableInertia(const Eigen::Vector3d& inertia);

}  // namespace fnmpc::model

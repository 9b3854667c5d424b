// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <limits>

#include "fnmpc/core/eigen_abi.hpp"

/// Scalar and Eigen aliases shared by every layer.
namespace fnmpc {

template <int Rows>
using Vec = Eigen::Matrix<double, Rows, 1>;
template <int Rows, int Cols>
using Mat = Eigen::Matrix<double, Rows, Cols>;

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using VecX = Eigen::VectorXd;
using MatX = Eigen::MatrixXd;

/// "Unset" marker (PX4 convention: a NaN setpoint is not set).
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// Infinite bound: a bound equal to +/-kInf is absent.
inline constexpr double kInf = std::numeric_limits<double>::infinity();
/// Standard gravity [m/s^2]; the world frame is ENU with z up.
inline constexpr double kGravity = 9.81;

}  // namespace fnmpc

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>
#include <cmath>
#include "fnmpc/core/eigen_abi.hpp"
#include "fnmpc/core/sin_cos.hpp"

/// Rotations in ZYX Euler convention: R = Rz(psi) * Ry(theta) * Rx(phi).
namespace fnmpc {

/// Third column of R = Rz(psi) Ry(theta) Rx(phi): the body z axis in the world frame.
/// Templated on the scalar so that models can be differentiated automatically.
template <class S>
Eigen::Matrix<S, 3, 1> BodyZ(const S& phi, const S& theta, const S& psi) {
  using std::cos;
  using std::sin;
  const S cphi = cos(phi), sphi = sin(phi), cth = cos(theta), sth = sin(theta);
  const S cpsi = cos(psi), spsi = sin(psi);
  return {cpsi * sth * cphi + spsi * sphi, spsi * sth * cphi - cpsi * sphi, cth * cphi};
}

/// BodyZ and its partial derivatives with respect to (phi, theta, psi) (columns of *dz)
/// from one evaluation of the six sines and cosines (SinCos: inline for angles within pi/4).
inline void BodyZAndJacobian(double phi, double theta, double psi, Eigen::Vector3d* z,
                             Eigen::Matrix3d* dz) {
  double cphi, sphi, cth, sth, cpsi, spsi;
  SinCos(phi, &sphi, &cphi);
  SinCos(theta, &sth, &cth);
  SinCos(psi, &spsi, &cpsi);
  *z << cpsi * sth * cphi + spsi * sphi, spsi * sth * cphi - cpsi * sphi, cth * cphi;
  *dz << -cpsi * sth * sphi + spsi * cphi, cpsi * cth * cphi, -spsi * sth * cphi + cpsi * sphi,
      -spsi * sth * sphi - cpsi * cphi, spsi * cth * cphi, cpsi * sth * cphi + spsi * sphi,
      -cth * sphi, -sth * cphi, 0.0;
}

/// Partial derivatives of BodyZ with respect to (phi, theta, psi), as columns.
inline Eigen::Matrix3d BodyZJacobian(double phi, double theta, double psi) {
  Eigen::Vector3d z;
  Eigen::Matrix3d J;
  BodyZAndJacobian(phi, theta, psi, &z, &J);
  return J;
}

/// Full rotation matrix R = Rz(psi) Ry(theta) Rx(phi) (body to world).
template <class S>
Eigen::Matrix<S, 3, 3> RotationZyx(const S& phi, const S& theta, const S& psi) {
  using std::cos;
  using std::sin;
  Eigen::Matrix<S, 3, 3> rz, ry, rx;
  rz << cos(psi), -sin(psi), S(0), sin(psi), cos(psi), S(0), S(0), S(0), S(1);
  ry << cos(theta), S(0), sin(theta), S(0), S(1), S(0), -sin(theta), S(0), cos(theta);
  rx << S(1), S(0), S(0), S(0), cos(phi), -sin(phi), S(0), sin(phi), cos(phi);
  return rz * ry * rx;
}

/// ZYX Euler angles (roll phi, pitch theta, yaw psi) of a rotation matrix R = Rz(psi) Ry(theta)
/// Rx(phi) [rad]; pitch in [-pi/2, pi/2].
inline Eigen::Vector3d EulerZyx(const Eigen::Matrix3d& r) {
  return {std::atan2(r(2, 1), r(2, 2)), -std::asin(std::clamp(r(2, 0), -1.0, 1.0)),
          std::atan2(r(1, 0), r(0, 0))};
}

/// Rotation about z by psi (the yaw-only "control frame" {c} of the reference work).
template <class S>
Eigen::Matrix<S, 3, 3> RotationZ(const S& psi) {
  using std::cos;
  using std::sin;
  Eigen::Matrix<S, 3, 3> rz;
  rz << cos(psi), -sin(psi), S(0), sin(psi), cos(psi), S(0), S(0), S(0), S(1);
  return rz;
}

/// Wraps an angle to (-pi, pi].
inline double WrapAngle(double a) {
  // Most angles are already wrapped, and std::remainder returns them unchanged: skip its cost.
  if (a > -M_PI && a <= M_PI) return a;
  a = std::remainder(a, 2.0 * M_PI);
  return a <= -M_PI ? a + 2.0 * M_PI : a;
}

}  // namespace fnmpc

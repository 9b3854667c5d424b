// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Core>
#include <cmath>

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
/// from one evaluation of the six sines and cosines.
inline void BodyZAndJacobian(double phi, double theta, double psi, Eigen::Vector3d* z,
                             Eigen::Matrix3d* dz);

/// BodyZAndJacobian from the sines and cosines of (phi, theta, psi).
inline void BodyZAndJacobian(const Eigen::Vector3d& sin, const Eigen::Vector3d& cos,
                             Eigen::Vector3d* z, Eigen::Matrix3d* dz) {
  const double sphi = sin[0], sth = sin[1], spsi = sin[2];
  const double cphi = cos[0], cth = cos[1], cpsi = cos[2];
  *z << cpsi * sth * cphi + spsi * sphi, spsi * sth * cphi - cpsi * sphi, cth * cphi;
  *dz << -cpsi * sth * sphi + spsi * cphi, cpsi * cth * cphi, -spsi * sth * cphi + cpsi * sphi,
      -spsi * sth * sphi - cpsi * cphi, spsi * cth * cphi, cpsi * sth * cphi + spsi * sphi,
      -cth * sphi, -sth * cphi, 0.0;
}

inline void BodyZAndJacobian(double phi, double theta, double psi, Eigen::Vector3d* z,
                             Eigen::Matrix3d* dz) {
  BodyZAndJacobian({std::sin(phi), std::sin(theta), std::sin(psi)},
                   {std::cos(phi), std::cos(theta), std::cos(psi)}, z, dz);
}

/// Largest offset SinCosNear takes [rad].
inline constexpr double kSinCosNearMax = 0.3;

/// sin(a0 + d) and cos(a0 + d), lane by lane, from sin(a0), cos(a0) and offsets |d| <=
/// kSinCosNearMax: the angle-addition formulas with sin d and cos d by their Taylor series
/// to degree 13 and 12 (truncation below 6e-19 there). Four lanes so that each Horner
/// step is one vector instruction with AVX: the RK4 stages of one shooting interval visit
/// eight nearby attitudes, and this is several times cheaper than libm's sincos for the
/// three angles while agreeing with it to a few units in the last place.
inline void SinCosNear(const Eigen::Array4d& sin_a0, const Eigen::Array4d& cos_a0,
                       const Eigen::Array4d& d, Eigen::Array4d* sin, Eigen::Array4d* cos) {
  // sin d = d (1 - d^2/(2 3) (1 - d^2/(4 5) (1 - ...))), cos d = 1 - d^2/(1 2) (1 - ...).
  static constexpr double kSin[6] = {1.0 / 6, 1.0 / 20, 1.0 / 42, 1.0 / 72, 1.0 / 110, 1.0 / 156};
  static constexpr double kCos[6] = {1.0 / 2, 1.0 / 12, 1.0 / 30, 1.0 / 56, 1.0 / 90, 1.0 / 132};
  const Eigen::Array4d d2 = d * d;
  Eigen::Array4d sd = Eigen::Array4d::Ones();
  Eigen::Array4d cd = Eigen::Array4d::Ones();
  for (int n = 5; n >= 0; --n) {
    sd = 1.0 - (kSin[n] * d2) * sd;
    cd = 1.0 - (kCos[n] * d2) * cd;
  }
  sd *= d;
  *sin = sin_a0 * cd + cos_a0 * sd;
  *cos = cos_a0 * cd - sin_a0 * sd;
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
  a = std::remainder(a, 2.0 * M_PI);
  return a <= -M_PI ? a + 2.0 * M_PI : a;
}

}  // namespace fnmpc

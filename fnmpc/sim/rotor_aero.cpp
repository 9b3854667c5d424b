// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/rotor_aero.hpp"

#include <algorithm>
#include <cmath>

namespace fnmpc::sim {

namespace {

/// Total inflow ratio lambda of the combined BEMT for climb inflow lambda_c.
double InflowRatio(double sa, double theta, double lambda_c) {
  const double b = sa / 4.0 - 2.0 * lambda_c;
  return (-b + std::sqrt(b * b + 4.0 * sa * theta / 3.0)) / 4.0;
}

}  // namespace

double AxialInflowThrustRatio(const RotorBlade& blade, double static_thrust, double omega,
                              double climb_velocity) {
  if (!(static_thrust > 0.0) || !(omega > 0.0)) return 1.0;
  const double tip = omega * blade.radius;
  const double area = M_PI * blade.radius * blade.radius;
  const double ct0 = static_thrust / (blade.air_density * area * tip * tip);
  const double sa = blade.solidity * blade.lift_slope;
  const double lambda_h = std::sqrt(ct0 / 2.0);
  // Effective pitch that makes the static thrust: C_T0 = (sa / 2) (theta / 3 - lambda_h / 2).
  const double theta = 3.0 * (2.0 * ct0 / sa + 0.5 * lambda_h);
  const double lambda_c = std::max(climb_velocity / tip, -lambda_h);
  const double lambda = InflowRatio(sa, theta, lambda_c);
  const double ct = std::max(0.0, 0.5 * sa * (theta / 3.0 - 0.5 * lambda));
  return ct / ct0;
}

double GroundEffectRatio(double radius, double height) {
  if (!(height > 0.0)) return 1.0;
  const double z = std::max(height, 0.5 * radius);
  const double q = radius / (4.0 * z);
  return 1.0 / (1.0 - q * q);
}

Vec3 RotorDrag(double d, double mass, double omega_ratio, const Vec3& axis, const Vec3& v_rel) {
  const Vec3 in_plane = v_rel - axis * axis.dot(v_rel);
  return (0.25 * mass * d * omega_ratio) * in_plane;
}

}  // namespace fnmpc::sim

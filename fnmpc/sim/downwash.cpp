// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/downwash.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace fnmpc::sim {

namespace {
void RequirePositive(double v, const char* name) {
  if (!(v > 0.0) || !std::isfinite(v)) {
    throw std::invalid_argument(std::string("[DownwashSettings] ") + name +
                                " must be finite and > 0, got " + std::to_string(v));
  }
}
}  // namespace

void DownwashSettings::Validate() const {
  RequirePositive(air_density, "air_density");
  RequirePositive(rotor_radius, "rotor_radius");
  RequirePositive(exit_velocity_factor, "exit_velocity_factor");
  RequirePositive(wake_radius, "wake_radius");
  RequirePositive(spreading_rate, "spreading_rate");
  RequirePositive(cutoff_half_widths, "cutoff_half_widths");
}

double HoverInducedVelocity(const DownwashSettings& s, double thrust) {
  if (!(thrust > 0.0)) return 0.0;
  const double area = 4.0 * M_PI * s.rotor_radius * s.rotor_radius;
  return std::sqrt(thrust / (2.0 * s.air_density * area));
}

Vec3 DownwashVelocity(const DownwashSettings& s, const Vec3& position, const Vec3& thrust_axis,
                      double thrust, const Vec3& point) {
  const double v_h = HoverInducedVelocity(s, thrust);
  if (v_h <= 0.0) return Vec3::Zero();
  const Vec3 d = point - position;
  const double dist = -d.dot(thrust_axis);  // downstream distance s
  if (dist <= 0.0) return Vec3::Zero();
  const double r = (d + dist * thrust_axis).norm();
  const double half_width = s.wake_radius + s.spreading_rate * dist;
  if (r > s.cutoff_half_widths * half_width) return Vec3::Zero();
  const double area = 4.0 * M_PI * s.rotor_radius * s.rotor_radius;
  const double u_centre = std::min(s.exit_velocity_factor * v_h,
                                   v_h * std::sqrt(4.0 * M_LN2 * area / M_PI) / half_width);
  const double eta = r / half_width;
  const double u = u_centre * std::exp(-M_LN2 * eta * eta);
  return -u * thrust_axis;
}

Vec3 QuadraticDrag(const Mat3& rotation, const Vec3& c, const Vec3& v_rel) {
  const double speed = v_rel.norm();
  if (speed == 0.0) return Vec3::Zero();
  const Vec3 v_b = rotation.transpose() * v_rel;
  return rotation * (c.cwiseProduct(v_b) * speed);
}

}  // namespace fnmpc::sim

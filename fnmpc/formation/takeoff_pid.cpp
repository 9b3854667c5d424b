// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/takeoff_pid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fnmpc::formation {

void TakeoffPidConfig::Validate() const {
  auto check = [](double v, const char* name) {
    if (!std::isfinite(v) || v < 0.0) {
      throw std::invalid_argument(std::string("[TakeoffPidConfig] ") + name +
                                  " must be finite and >= 0, got " + std::to_string(v));
    }
  };
  check(kp_z, "kp_z");
  check(kd_z, "kd_z");
  check(ki_z, "ki_z");
  check(kp_xy, "kp_xy");
  check(kv_xy, "kv_xy");
  check(ki_xy, "ki_xy");
  check(max_integral_xy, "max_integral_xy");
  check(max_tilt, "max_tilt");
  check(max_thrust, "max_thrust");
}

TakeoffPid::TakeoffPid(const TakeoffPidConfig& config, double mass) : config_(config), mass_(mass) {
  config_.Validate();
  if (!(mass > 0.0)) throw std::invalid_argument("[TakeoffPid] mass must be > 0");
  // Anti-windup from the actuator: the integral never asks for more than the thrust bound
  // gives in level flight, nor for less than zero thrust.
  max_integral_ = std::max(0.0, config_.max_thrust / mass_ - kGravity);
}

void TakeoffPid::Reset(double thrust) {
  integral_ =
      std::isfinite(thrust) ? std::clamp(thrust / mass_ - kGravity, -kGravity, max_integral_) : 0.0;
  integral_xy_.setZero();
}

PidCommand TakeoffPid::Update(double dt, double z_ref, double vz_ref, double z,
                              const Vec3& velocity, const Vec3& euler, const Vec<2>& xy_error) {
  PidCommand c;
  const double ez = z_ref - z;
  if (std::isfinite(ez) && dt > 0.0) {
    integral_ = std::clamp(integral_ + config_.ki_z * ez * dt, -kGravity, max_integral_);
  }
  const double az = config_.kp_z * ez + config_.kd_z * (vz_ref - velocity.z()) + integral_;
  const double tilt = std::max(0.5, std::cos(euler.x()) * std::cos(euler.y()));
  c.thrust = std::clamp(mass_ * (kGravity + az) / tilt, 0.0, config_.max_thrust);
  if (!std::isfinite(az) || !std::isfinite(tilt)) c.thrust = kNaN;
  Vec<2> a = -config_.kv_xy * velocity.head<2>();
  if (xy_error.allFinite()) {
    if (dt > 0.0) {
      integral_xy_ = (integral_xy_ + config_.ki_xy * dt * xy_error)
                         .cwiseMax(-config_.max_integral_xy)
                         .cwiseMin(config_.max_integral_xy);
    }
    a += config_.kp_xy * xy_error + integral_xy_;
  }
  const double ax = a.x(), ay = a.y();
  const double cy = std::cos(euler.z()), sy = std::sin(euler.z());
  c.pitch = std::clamp((ax * cy + ay * sy) / kGravity, -config_.max_tilt, config_.max_tilt);
  c.roll = std::clamp((ax * sy - ay * cy) / kGravity, -config_.max_tilt, config_.max_tilt);
  if (!std::isfinite(ax + ay + euler.z())) c.roll = c.pitch = kNaN;
  return c;
}

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/autopilot/setpoint.hpp"

#include <cmath>

#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/mavlink/frame_conversions.hpp"

namespace fnmpc::autopilot {

bool AttitudeSetpoint::valid() const {
  return std::isfinite(roll) && std::isfinite(pitch) && std::isfinite(yaw) &&
         std::isfinite(thrust) && thrust >= 0.0 && thrust <= 1.0;
}

mavlink::SetAttitudeTarget ToSetAttitudeTarget(const AttitudeSetpoint& setpoint,
                                               std::uint32_t time_boot_ms,
                                               std::uint8_t target_system,
                                               std::uint8_t target_component) {
  const Eigen::Quaterniond q_enu_flu(RotationZyx(setpoint.roll, setpoint.pitch, setpoint.yaw));
  mavlink::SetAttitudeTarget m;
  m.time_boot_ms = time_boot_ms;
  m.q = mavlink::QuaternionToWxyz(mavlink::EnuFluToNedFrd(q_enu_flu).normalized());
  m.thrust = static_cast<float>(setpoint.thrust);
  m.target_system = target_system;
  m.target_component = target_component;
  m.type_mask = mav::kIgnoreBodyRates;
  return m;
}

AttitudeSetpoint FromSetAttitudeTarget(const mavlink::SetAttitudeTarget& message) {
  AttitudeSetpoint s;
  // ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE, _ATTITUDE_IGNORE: nothing to fly.
  constexpr std::uint8_t kIgnoreThrustOrAttitude = 1U << 6 | 1U << 7;
  const Eigen::Quaterniond q = mavlink::QuaternionFromWxyz(message.q);
  if ((message.type_mask & kIgnoreThrustOrAttitude) != 0 || !std::isfinite(q.norm()) ||
      q.norm() < 0.5) {
    return s;
  }
  const Vec3 rpy = EulerZyx(mavlink::NedFrdToEnuFlu(q.normalized()).toRotationMatrix());
  s.roll = rpy.x();
  s.pitch = rpy.y();
  s.yaw = rpy.z();
  s.thrust = message.thrust;
  return s;
}

}  // namespace fnmpc::autopilot

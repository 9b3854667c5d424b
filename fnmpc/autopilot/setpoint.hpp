// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>

#include "fnmpc/core/types.hpp"
#include "fnmpc/mavlink/messages.hpp"

namespace fnmpc::autopilot {

/// An attitude and collective thrust setpoint in fnmpc's frames: ZYX Euler angles of the FLU
/// body in ENU [rad] and the thrust normalised to [0, 1] the way the autopilot expects it
/// (docs/autopilot.md "Thrust": the identified throttle polynomial at the live battery
/// voltage, formation::ThrustToThrottle).
struct AttitudeSetpoint {
  double roll = kNaN, pitch = kNaN, yaw = kNaN;
  double thrust = kNaN;
  /// Every field finite and the thrust within [0, 1]: only such a setpoint is ever sent.
  [[nodiscard]] bool valid() const;
};

/// SET_ATTITUDE_TARGET carrying `setpoint` (ENU/FLU -> NED/FRD quaternion, body rates
/// ignored) to (target_system, target_component), stamped `time_boot_ms`.
mavlink::SetAttitudeTarget ToSetAttitudeTarget(const AttitudeSetpoint& setpoint,
                                               std::uint32_t time_boot_ms,
                                               std::uint8_t target_system,
                                               std::uint8_t target_component);
/// The setpoint a SET_ATTITUDE_TARGET carries (its quaternion normalised; invalid when the
/// quaternion is degenerate or the type mask ignores the attitude or the thrust).
AttitudeSetpoint FromSetAttitudeTarget(const mavlink::SetAttitudeTarget& message);

}  // namespace fnmpc::autopilot

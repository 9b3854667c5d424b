// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <string_view>

/// Autopilot families, their flight-mode encodings and the MAVLink enum values the sessions
/// use (common.xml; PX4's px4_custom_mode.h; ArduPilot's Copter mode numbers).
namespace fnmpc::autopilot {

enum class AutopilotKind : int {
  kPx4 = 0,        ///< PX4: OFFBOARD mode, custom_mode = main mode << 16 | sub mode << 24
  kArduPilot = 1,  ///< ArduPilot Copter: GUIDED_NOGPS (20), custom_mode = mode number
};
std::string_view ToString(AutopilotKind kind);
/// "px4" or "ardupilot"; throws std::invalid_argument naming the accepted values.
AutopilotKind ParseAutopilotKind(std::string_view text);

/// The flight modes the link distinguishes.
enum class FlightMode : int {
  kOther = 0,     ///< any mode in which the autopilot does not fly our setpoints
  kOffboard = 1,  ///< PX4 OFFBOARD / ArduPilot GUIDED_NOGPS: attitude setpoints from us
  kLand = 2,      ///< PX4 AUTO.LAND / ArduPilot LAND: the autopilot's own landing
};
std::string_view ToString(FlightMode mode);

/// HEARTBEAT custom_mode of `mode` (kOther: PX4 POSCTL, ArduPilot STABILIZE).
std::uint32_t CustomMode(AutopilotKind kind, FlightMode mode);
/// The mode a HEARTBEAT's custom_mode encodes.
FlightMode ModeOf(AutopilotKind kind, std::uint32_t custom_mode);

/// MAV_CMD_DO_SET_MODE parameters of `mode`: param1 = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
/// param2 = PX4 main mode / ArduPilot mode number, param3 = PX4 sub mode.
struct SetModeParams {
  float base_mode = 1.0F;
  float custom_main = 0.0F;
  float custom_sub = 0.0F;
};
SetModeParams SetModeParamsOf(AutopilotKind kind, FlightMode mode);
/// The mode a DO_SET_MODE request asks for.
FlightMode ModeOf(AutopilotKind kind, const SetModeParams& params);

/// MAVLink values (common.xml) the sessions use.
namespace mav {
inline constexpr std::uint16_t kCmdDoSetMode = 176;            // MAV_CMD_DO_SET_MODE
inline constexpr std::uint16_t kCmdComponentArmDisarm = 400;   // MAV_CMD_COMPONENT_ARM_DISARM
inline constexpr std::uint16_t kCmdSetMessageInterval = 511;   // MAV_CMD_SET_MESSAGE_INTERVAL
inline constexpr std::uint8_t kResultAccepted = 0;             // MAV_RESULT_ACCEPTED
inline constexpr std::uint8_t kResultTemporarilyRejected = 1;  // MAV_RESULT_TEMPORARILY_REJECTED
inline constexpr std::uint8_t kResultDenied = 2;               // MAV_RESULT_DENIED
inline constexpr std::uint8_t kResultUnsupported = 3;          // MAV_RESULT_UNSUPPORTED
inline constexpr std::uint8_t kResultFailed = 4;               // MAV_RESULT_FAILED
inline constexpr std::uint8_t kResultInProgress = 5;           // MAV_RESULT_IN_PROGRESS
inline constexpr std::uint8_t kModeFlagCustomModeEnabled = 1;  // MAV_MODE_FLAG_*
inline constexpr std::uint8_t kModeFlagSafetyArmed = 128;
inline constexpr std::uint8_t kTypeQuadrotor = 2;           // MAV_TYPE_QUADROTOR
inline constexpr std::uint8_t kTypeOnboardController = 18;  // MAV_TYPE_ONBOARD_CONTROLLER
inline constexpr std::uint8_t kAutopilotArduPilotMega = 3;  // MAV_AUTOPILOT_ARDUPILOTMEGA
inline constexpr std::uint8_t kAutopilotInvalid = 8;        // MAV_AUTOPILOT_INVALID
inline constexpr std::uint8_t kAutopilotPx4 = 12;           // MAV_AUTOPILOT_PX4
inline constexpr std::uint8_t kStateStandby = 3;            // MAV_STATE_*
inline constexpr std::uint8_t kStateActive = 4;
inline constexpr std::uint8_t kStateCritical = 5;
inline constexpr std::uint8_t kCompAutopilot = 1;          // MAV_COMP_ID_AUTOPILOT1
inline constexpr std::uint8_t kCompOnboardComputer = 191;  // MAV_COMP_ID_ONBOARD_COMPUTER
inline constexpr std::uint8_t kFrameLocalNed = 1;          // MAV_FRAME_LOCAL_NED
inline constexpr std::uint8_t kFrameBodyFrd = 12;          // MAV_FRAME_BODY_FRD
inline constexpr std::uint8_t kEstimatorVio = 3;           // MAV_ESTIMATOR_TYPE_VIO
inline constexpr std::uint8_t kEstimatorMocap = 6;         // MAV_ESTIMATOR_TYPE_MOCAP
/// ATTITUDE_TARGET_TYPEMASK: ignore the three body rates (attitude + thrust only).
inline constexpr std::uint8_t kIgnoreBodyRates = 0b0000'0111;
/// SYS_STATUS onboard_control_sensors_*: MAV_SYS_STATUS_SENSOR_BATTERY.
inline constexpr std::uint32_t kSensorBattery = 1U << 25;
}  // namespace mav

}  // namespace fnmpc::autopilot

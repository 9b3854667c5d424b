// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

/// The supported MAVLink messages (common.xml), as plain structs: exactly the message's fields
/// with their MAVLink names and types, in MAVLink units (not SI: mV, cA, cdegC, ... as
/// each comment says), in wire order (base fields sorted by type size, stable; then the
/// extensions in the order of the XML). Frames are the message's own (mostly NED/FRD;
/// frame_conversions.hpp converts to the project's ENU/FLU). Each struct states
///   kId         message id
///   kName       MAVLink name (enters CRC_EXTRA)
///   kCrcExtra   CRC_EXTRA seed byte of the checksum
///   kMinLength  payload length of the base fields [bytes]
///   kMaxLength  payload length with the extensions [bytes]
/// and VisitFields (message_layout.hpp), from which pack/unpack are derived and those
/// constants checked at compile time. Default-initialised fields are zero, which is also
/// what a receiver reads for fields missing from a truncated payload.
namespace fnmpc::mavlink {

/// HEARTBEAT (0): the system's type, autopilot and mode; sent at 1 Hz by every component.
struct Heartbeat {
  static constexpr std::uint32_t kId = 0;
  static constexpr std::string_view kName = "HEARTBEAT";
  static constexpr std::uint8_t kCrcExtra = 50;
  static constexpr std::size_t kMinLength = 9;
  static constexpr std::size_t kMaxLength = 9;

  std::uint32_t custom_mode{};     ///< autopilot-specific flags
  std::uint8_t type{};             ///< MAV_TYPE
  std::uint8_t autopilot{};        ///< MAV_AUTOPILOT
  std::uint8_t base_mode{};        ///< MAV_MODE_FLAG bitmap
  std::uint8_t system_status{};    ///< MAV_STATE
  std::uint8_t mavlink_version{};  ///< MAVLink protocol version, 3 (senders set it)

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("custom_mode", m.custom_mode);
    v.Field("type", m.type);
    v.Field("autopilot", m.autopilot);
    v.Field("base_mode", m.base_mode);
    v.Field("system_status", m.system_status);
    v.Field("mavlink_version", m.mavlink_version);
  }
  friend bool operator==(const Heartbeat&, const Heartbeat&) = default;
};

/// SYS_STATUS (1): onboard sensors, battery, communication errors.
struct SysStatus {
  static constexpr std::uint32_t kId = 1;
  static constexpr std::string_view kName = "SYS_STATUS";
  static constexpr std::uint8_t kCrcExtra = 124;
  static constexpr std::size_t kMinLength = 31;
  static constexpr std::size_t kMaxLength = 43;

  std::uint32_t onboard_control_sensors_present{};  ///< MAV_SYS_STATUS_SENSOR bitmap
  std::uint32_t onboard_control_sensors_enabled{};  ///< MAV_SYS_STATUS_SENSOR bitmap
  std::uint32_t onboard_control_sensors_health{};   ///< MAV_SYS_STATUS_SENSOR bitmap
  std::uint16_t load{};                             ///< main-loop load [d%] (0.1 %, 1000 = 100 %)
  std::uint16_t voltage_battery{};                  ///< battery voltage [mV], UINT16_MAX: unknown
  std::int16_t current_battery{};                   ///< battery current [cA], -1: unknown
  std::uint16_t drop_rate_comm{};                   ///< dropped packets [c%]
  std::uint16_t errors_comm{};                      ///< communication errors
  std::uint16_t errors_count1{};                    ///< autopilot-specific errors
  std::uint16_t errors_count2{};                    ///< autopilot-specific errors
  std::uint16_t errors_count3{};                    ///< autopilot-specific errors
  std::uint16_t errors_count4{};                    ///< autopilot-specific errors
  std::int8_t battery_remaining{};                  ///< remaining battery [%], -1: unknown
  // Extensions.
  std::uint32_t onboard_control_sensors_present_extended{};  ///< MAV_SYS_STATUS_SENSOR_EXTENDED
  std::uint32_t onboard_control_sensors_enabled_extended{};  ///< MAV_SYS_STATUS_SENSOR_EXTENDED
  std::uint32_t onboard_control_sensors_health_extended{};   ///< MAV_SYS_STATUS_SENSOR_EXTENDED

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("onboard_control_sensors_present", m.onboard_control_sensors_present);
    v.Field("onboard_control_sensors_enabled", m.onboard_control_sensors_enabled);
    v.Field("onboard_control_sensors_health", m.onboard_control_sensors_health);
    v.Field("load", m.load);
    v.Field("voltage_battery", m.voltage_battery);
    v.Field("current_battery", m.current_battery);
    v.Field("drop_rate_comm", m.drop_rate_comm);
    v.Field("errors_comm", m.errors_comm);
    v.Field("errors_count1", m.errors_count1);
    v.Field("errors_count2", m.errors_count2);
    v.Field("errors_count3", m.errors_count3);
    v.Field("errors_count4", m.errors_count4);
    v.Field("battery_remaining", m.battery_remaining);
    v.Extension("onboard_control_sensors_present_extended",
                m.onboard_control_sensors_present_extended);
    v.Extension("onboard_control_sensors_enabled_extended",
                m.onboard_control_sensors_enabled_extended);
    v.Extension("onboard_control_sensors_health_extended",
                m.onboard_control_sensors_health_extended);
  }
  friend bool operator==(const SysStatus&, const SysStatus&) = default;
};

/// BATTERY_STATUS (147): one battery's cells, current, consumption and state.
struct BatteryStatus {
  static constexpr std::uint32_t kId = 147;
  static constexpr std::string_view kName = "BATTERY_STATUS";
  static constexpr std::uint8_t kCrcExtra = 154;
  static constexpr std::size_t kMinLength = 36;
  static constexpr std::size_t kMaxLength = 54;

  std::int32_t current_consumed{};           ///< consumed charge [mAh], -1: not provided
  std::int32_t energy_consumed{};            ///< consumed energy [hJ], -1: not provided
  std::int16_t temperature{};                ///< temperature [cdegC], INT16_MAX: unknown
  std::array<std::uint16_t, 10> voltages{};  ///< cell voltages 1-10 [mV], UINT16_MAX: unused
  std::int16_t current_battery{};            ///< battery current [cA], -1: not measured
  std::uint8_t id{};                         ///< battery id
  std::uint8_t battery_function{};           ///< MAV_BATTERY_FUNCTION
  std::uint8_t type{};                       ///< MAV_BATTERY_TYPE
  std::int8_t battery_remaining{};           ///< remaining energy [%], -1: not provided
  // Extensions.
  std::int32_t time_remaining{};                ///< remaining time [s], 0: not provided
  std::uint8_t charge_state{};                  ///< MAV_BATTERY_CHARGE_STATE
  std::array<std::uint16_t, 4> voltages_ext{};  ///< cell voltages 11-14 [mV], 0: unused
  std::uint8_t mode{};                          ///< MAV_BATTERY_MODE
  std::uint32_t fault_bitmask{};                ///< MAV_BATTERY_FAULT bitmap

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("current_consumed", m.current_consumed);
    v.Field("energy_consumed", m.energy_consumed);
    v.Field("temperature", m.temperature);
    v.Field("voltages", m.voltages);
    v.Field("current_battery", m.current_battery);
    v.Field("id", m.id);
    v.Field("battery_function", m.battery_function);
    v.Field("type", m.type);
    v.Field("battery_remaining", m.battery_remaining);
    v.Extension("time_remaining", m.time_remaining);
    v.Extension("charge_state", m.charge_state);
    v.Extension("voltages_ext", m.voltages_ext);
    v.Extension("mode", m.mode);
    v.Extension("fault_bitmask", m.fault_bitmask);
  }
  friend bool operator==(const BatteryStatus&, const BatteryStatus&) = default;
};

/// ATTITUDE (30): ZYX Euler angles of the body (FRD) in NED, and body rates.
struct Attitude {
  static constexpr std::uint32_t kId = 30;
  static constexpr std::string_view kName = "ATTITUDE";
  static constexpr std::uint8_t kCrcExtra = 39;
  static constexpr std::size_t kMinLength = 28;
  static constexpr std::size_t kMaxLength = 28;

  std::uint32_t time_boot_ms{};  ///< time since boot [ms]
  float roll{};                  ///< roll angle [rad] (-pi..+pi)
  float pitch{};                 ///< pitch angle [rad] (-pi..+pi)
  float yaw{};                   ///< yaw angle [rad] (-pi..+pi), 0 = north, clockwise
  float rollspeed{};             ///< roll rate [rad/s]
  float pitchspeed{};            ///< pitch rate [rad/s]
  float yawspeed{};              ///< yaw rate [rad/s]

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("time_boot_ms", m.time_boot_ms);
    v.Field("roll", m.roll);
    v.Field("pitch", m.pitch);
    v.Field("yaw", m.yaw);
    v.Field("rollspeed", m.rollspeed);
    v.Field("pitchspeed", m.pitchspeed);
    v.Field("yawspeed", m.yawspeed);
  }
  friend bool operator==(const Attitude&, const Attitude&) = default;
};

/// ATTITUDE_QUATERNION (31): attitude quaternion (w, x, y, z) of the body (FRD) in NED.
struct AttitudeQuaternion {
  static constexpr std::uint32_t kId = 31;
  static constexpr std::string_view kName = "ATTITUDE_QUATERNION";
  static constexpr std::uint8_t kCrcExtra = 246;
  static constexpr std::size_t kMinLength = 32;
  static constexpr std::size_t kMaxLength = 48;

  std::uint32_t time_boot_ms{};  ///< time since boot [ms]
  float q1{};                    ///< quaternion w (1 at the null rotation)
  float q2{};                    ///< quaternion x
  float q3{};                    ///< quaternion y
  float q4{};                    ///< quaternion z
  float rollspeed{};             ///< roll rate [rad/s]
  float pitchspeed{};            ///< pitch rate [rad/s]
  float yawspeed{};              ///< yaw rate [rad/s]
  // Extensions.
  std::array<float, 4> repr_offset_q{};  ///< rotation offset (w, x, y, z) for display; zeros: none

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("time_boot_ms", m.time_boot_ms);
    v.Field("q1", m.q1);
    v.Field("q2", m.q2);
    v.Field("q3", m.q3);
    v.Field("q4", m.q4);
    v.Field("rollspeed", m.rollspeed);
    v.Field("pitchspeed", m.pitchspeed);
    v.Field("yawspeed", m.yawspeed);
    v.Extension("repr_offset_q", m.repr_offset_q);
  }
  friend bool operator==(const AttitudeQuaternion&, const AttitudeQuaternion&) = default;
};

/// LOCAL_POSITION_NED (32): position and velocity in the local NED frame.
struct LocalPositionNed {
  static constexpr std::uint32_t kId = 32;
  static constexpr std::string_view kName = "LOCAL_POSITION_NED";
  static constexpr std::uint8_t kCrcExtra = 185;
  static constexpr std::size_t kMinLength = 28;
  static constexpr std::size_t kMaxLength = 28;

  std::uint32_t time_boot_ms{};  ///< time since boot [ms]
  float x{};                     ///< north [m]
  float y{};                     ///< east [m]
  float z{};                     ///< down [m]
  float vx{};                    ///< north velocity [m/s]
  float vy{};                    ///< east velocity [m/s]
  float vz{};                    ///< down velocity [m/s]

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("time_boot_ms", m.time_boot_ms);
    v.Field("x", m.x);
    v.Field("y", m.y);
    v.Field("z", m.z);
    v.Field("vx", m.vx);
    v.Field("vy", m.vy);
    v.Field("vz", m.vz);
  }
  friend bool operator==(const LocalPositionNed&, const LocalPositionNed&) = default;
};

/// ODOMETRY (331): pose, velocity, rates and covariances (frames given by frame_id and
/// child_frame_id, MAV_FRAME).
struct Odometry {
  static constexpr std::uint32_t kId = 331;
  static constexpr std::string_view kName = "ODOMETRY";
  static constexpr std::uint8_t kCrcExtra = 91;
  static constexpr std::size_t kMinLength = 230;
  static constexpr std::size_t kMaxLength = 233;

  std::uint64_t time_usec{};                ///< timestamp [us] (since boot or Unix epoch)
  float x{};                                ///< x position [m]
  float y{};                                ///< y position [m]
  float z{};                                ///< z position [m]
  std::array<float, 4> q{};                 ///< quaternion (w, x, y, z), child frame in frame_id
  float vx{};                               ///< x velocity [m/s] (in child_frame_id)
  float vy{};                               ///< y velocity [m/s]
  float vz{};                               ///< z velocity [m/s]
  float rollspeed{};                        ///< roll rate [rad/s]
  float pitchspeed{};                       ///< pitch rate [rad/s]
  float yawspeed{};                         ///< yaw rate [rad/s]
  std::array<float, 21> pose_covariance{};  ///< upper triangle of the 6x6 (x y z roll pitch yaw)
                                            ///< covariance, row-major; NaN first: unknown
  std::array<float, 21> velocity_covariance{};  ///< upper triangle of the 6x6 (vx vy vz rates)
                                                ///< covariance, row-major; NaN first: unknown
  std::uint8_t frame_id{};                      ///< MAV_FRAME of the pose
  std::uint8_t child_frame_id{};                ///< MAV_FRAME of the velocity
  // Extensions.
  std::uint8_t reset_counter{};   ///< incremented at each estimator reset
  std::uint8_t estimator_type{};  ///< MAV_ESTIMATOR_TYPE
  std::int8_t quality{};          ///< quality [%], -1: failed, 0: unknown, 1 worst .. 100 best

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("time_usec", m.time_usec);
    v.Field("x", m.x);
    v.Field("y", m.y);
    v.Field("z", m.z);
    v.Field("q", m.q);
    v.Field("vx", m.vx);
    v.Field("vy", m.vy);
    v.Field("vz", m.vz);
    v.Field("rollspeed", m.rollspeed);
    v.Field("pitchspeed", m.pitchspeed);
    v.Field("yawspeed", m.yawspeed);
    v.Field("pose_covariance", m.pose_covariance);
    v.Field("velocity_covariance", m.velocity_covariance);
    v.Field("frame_id", m.frame_id);
    v.Field("child_frame_id", m.child_frame_id);
    v.Extension("reset_counter", m.reset_counter);
    v.Extension("estimator_type", m.estimator_type);
    v.Extension("quality", m.quality);
  }
  friend bool operator==(const Odometry&, const Odometry&) = default;
};

/// HIGHRES_IMU (105): IMU readings in the body frame (FRD) in SI units.
struct HighresImu {
  static constexpr std::uint32_t kId = 105;
  static constexpr std::string_view kName = "HIGHRES_IMU";
  static constexpr std::uint8_t kCrcExtra = 93;
  static constexpr std::size_t kMinLength = 62;
  static constexpr std::size_t kMaxLength = 63;

  std::uint64_t time_usec{};       ///< timestamp [us] (since boot or Unix epoch)
  float xacc{};                    ///< x acceleration (specific force) [m/s^2]
  float yacc{};                    ///< y acceleration [m/s^2]
  float zacc{};                    ///< z acceleration [m/s^2]
  float xgyro{};                   ///< angular rate about x [rad/s]
  float ygyro{};                   ///< angular rate about y [rad/s]
  float zgyro{};                   ///< angular rate about z [rad/s]
  float xmag{};                    ///< x magnetic field [gauss]
  float ymag{};                    ///< y magnetic field [gauss]
  float zmag{};                    ///< z magnetic field [gauss]
  float abs_pressure{};            ///< absolute pressure [hPa]
  float diff_pressure{};           ///< differential pressure [hPa]
  float pressure_alt{};            ///< altitude from pressure
  float temperature{};             ///< temperature [degC]
  std::uint16_t fields_updated{};  ///< HIGHRES_IMU_UPDATED_FLAGS bitmap
  // Extensions.
  std::uint8_t id{};  ///< IMU instance (0-based)

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("time_usec", m.time_usec);
    v.Field("xacc", m.xacc);
    v.Field("yacc", m.yacc);
    v.Field("zacc", m.zacc);
    v.Field("xgyro", m.xgyro);
    v.Field("ygyro", m.ygyro);
    v.Field("zgyro", m.zgyro);
    v.Field("xmag", m.xmag);
    v.Field("ymag", m.ymag);
    v.Field("zmag", m.zmag);
    v.Field("abs_pressure", m.abs_pressure);
    v.Field("diff_pressure", m.diff_pressure);
    v.Field("pressure_alt", m.pressure_alt);
    v.Field("temperature", m.temperature);
    v.Field("fields_updated", m.fields_updated);
    v.Extension("id", m.id);
  }
  friend bool operator==(const HighresImu&, const HighresImu&) = default;
};

/// SET_ATTITUDE_TARGET (82): attitude (body FRD in NED), body rate and thrust setpoint to
/// the autopilot.
struct SetAttitudeTarget {
  static constexpr std::uint32_t kId = 82;
  static constexpr std::string_view kName = "SET_ATTITUDE_TARGET";
  static constexpr std::uint8_t kCrcExtra = 49;
  static constexpr std::size_t kMinLength = 39;
  static constexpr std::size_t kMaxLength = 51;

  std::uint32_t time_boot_ms{};  ///< time since boot [ms]
  std::array<float, 4> q{};      ///< attitude quaternion (w, x, y, z), FRD body in NED
  float body_roll_rate{};        ///< body roll rate [rad/s]
  float body_pitch_rate{};       ///< body pitch rate [rad/s]
  float body_yaw_rate{};         ///< body yaw rate [rad/s]
  float thrust{};                ///< collective thrust, normalised to 0..1 (-1..1 for reversible)
  std::uint8_t target_system{};  ///< system id
  std::uint8_t target_component{};  ///< component id
  std::uint8_t type_mask{};         ///< ATTITUDE_TARGET_TYPEMASK: fields to ignore
  // Extensions.
  std::array<float, 3> thrust_body{};  ///< 3-D thrust setpoint in the body frame (FRD), -1..1

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("time_boot_ms", m.time_boot_ms);
    v.Field("q", m.q);
    v.Field("body_roll_rate", m.body_roll_rate);
    v.Field("body_pitch_rate", m.body_pitch_rate);
    v.Field("body_yaw_rate", m.body_yaw_rate);
    v.Field("thrust", m.thrust);
    v.Field("target_system", m.target_system);
    v.Field("target_component", m.target_component);
    v.Field("type_mask", m.type_mask);
    v.Extension("thrust_body", m.thrust_body);
  }
  friend bool operator==(const SetAttitudeTarget&, const SetAttitudeTarget&) = default;
};

/// ATTITUDE_TARGET (83): the autopilot's current attitude setpoint (echo of
/// SET_ATTITUDE_TARGET).
struct AttitudeTarget {
  static constexpr std::uint32_t kId = 83;
  static constexpr std::string_view kName = "ATTITUDE_TARGET";
  static constexpr std::uint8_t kCrcExtra = 22;
  static constexpr std::size_t kMinLength = 37;
  static constexpr std::size_t kMaxLength = 37;

  std::uint32_t time_boot_ms{};  ///< time since boot [ms]
  std::array<float, 4> q{};      ///< attitude quaternion (w, x, y, z), FRD body in NED
  float body_roll_rate{};        ///< body roll rate [rad/s]
  float body_pitch_rate{};       ///< body pitch rate [rad/s]
  float body_yaw_rate{};         ///< body yaw rate [rad/s]
  float thrust{};                ///< collective thrust, normalised to 0..1 (-1..1 for reversible)
  std::uint8_t type_mask{};      ///< ATTITUDE_TARGET_TYPEMASK: fields to ignore

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("time_boot_ms", m.time_boot_ms);
    v.Field("q", m.q);
    v.Field("body_roll_rate", m.body_roll_rate);
    v.Field("body_pitch_rate", m.body_pitch_rate);
    v.Field("body_yaw_rate", m.body_yaw_rate);
    v.Field("thrust", m.thrust);
    v.Field("type_mask", m.type_mask);
  }
  friend bool operator==(const AttitudeTarget&, const AttitudeTarget&) = default;
};

/// COMMAND_LONG (76): a MAV_CMD with seven float parameters.
struct CommandLong {
  static constexpr std::uint32_t kId = 76;
  static constexpr std::string_view kName = "COMMAND_LONG";
  static constexpr std::uint8_t kCrcExtra = 152;
  static constexpr std::size_t kMinLength = 33;
  static constexpr std::size_t kMaxLength = 33;

  float param1{};                   ///< parameter 1 (meaning per command)
  float param2{};                   ///< parameter 2
  float param3{};                   ///< parameter 3
  float param4{};                   ///< parameter 4
  float param5{};                   ///< parameter 5
  float param6{};                   ///< parameter 6
  float param7{};                   ///< parameter 7
  std::uint16_t command{};          ///< MAV_CMD
  std::uint8_t target_system{};     ///< system id
  std::uint8_t target_component{};  ///< component id
  std::uint8_t confirmation{};      ///< 0 first transmission, then incremented per resend

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("param1", m.param1);
    v.Field("param2", m.param2);
    v.Field("param3", m.param3);
    v.Field("param4", m.param4);
    v.Field("param5", m.param5);
    v.Field("param6", m.param6);
    v.Field("param7", m.param7);
    v.Field("command", m.command);
    v.Field("target_system", m.target_system);
    v.Field("target_component", m.target_component);
    v.Field("confirmation", m.confirmation);
  }
  friend bool operator==(const CommandLong&, const CommandLong&) = default;
};

/// COMMAND_ACK (77): the result of a command.
struct CommandAck {
  static constexpr std::uint32_t kId = 77;
  static constexpr std::string_view kName = "COMMAND_ACK";
  static constexpr std::uint8_t kCrcExtra = 143;
  static constexpr std::size_t kMinLength = 3;
  static constexpr std::size_t kMaxLength = 10;

  std::uint16_t command{};  ///< MAV_CMD acknowledged
  std::uint8_t result{};    ///< MAV_RESULT
  // Extensions.
  std::uint8_t progress{};          ///< progress [%] with MAV_RESULT_IN_PROGRESS, 255: unknown
  std::int32_t result_param2{};     ///< additional result information (per command)
  std::uint8_t target_system{};     ///< system that sent the command
  std::uint8_t target_component{};  ///< component that sent the command

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("command", m.command);
    v.Field("result", m.result);
    v.Extension("progress", m.progress);
    v.Extension("result_param2", m.result_param2);
    v.Extension("target_system", m.target_system);
    v.Extension("target_component", m.target_component);
  }
  friend bool operator==(const CommandAck&, const CommandAck&) = default;
};

/// FNMPC_RELATIVE_OBSERVATION (53100), fnmpc's own dialect: one vehicle seen by the relative
/// sensor of the sending vehicle (range, bearing, elevation and relative yaw, as
/// fnmpc::RelativeObservation). No common.xml message carries such an observation; it is
/// what the simulator's MAVLink endpoint sends for the relative sensor (docs/autopilot.md).
/// Angles are in fnmpc's frames, not MAVLink's: the offset d_B is in the observer's FLU body
/// frame, bearing = atan2(d_B.y, d_B.x), elevation = asin(d_B.z / range), relative yaw
/// counter-clockwise positive.
struct FnmpcRelativeObservation {
  static constexpr std::uint32_t kId = 53100;
  static constexpr std::string_view kName = "FNMPC_RELATIVE_OBSERVATION";
  static constexpr std::string_view kDialect = "fnmpc";
  static constexpr std::uint8_t kCrcExtra = 135;
  static constexpr std::size_t kMinLength = 25;
  static constexpr std::size_t kMaxLength = 25;

  std::uint64_t time_usec{};     ///< time of validity [us] (the sender's clock)
  float range{};                 ///< [m]
  float bearing{};               ///< [rad]
  float elevation{};             ///< [rad]
  float relative_yaw{};          ///< yaw of the target minus the observer's [rad]
  std::uint8_t target_system{};  ///< system id of the observed vehicle

  template <class Self, class V>
  static constexpr void VisitFields(Self& m, V& v) {
    v.Field("time_usec", m.time_usec);
    v.Field("range", m.range);
    v.Field("bearing", m.bearing);
    v.Field("elevation", m.elevation);
    v.Field("relative_yaw", m.relative_yaw);
    v.Field("target_system", m.target_system);
  }
  friend bool operator==(const FnmpcRelativeObservation&,
                         const FnmpcRelativeObservation&) = default;
};

}  // namespace fnmpc::mavlink

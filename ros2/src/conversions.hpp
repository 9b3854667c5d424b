// SPDX-License-Identifier: BSD-3-Clause
// fnmpc value types <-> the ROS 2 messages of ros2/ (docs/ros2.md). Pure functions, no node
// logic. Frames as in the ROS 1 package: world ENU z up ("world"), body FLU
// ("<vehicle>/base_link"), Euler ZYX, SI units. String fields of the messages built here point
// to the `const char*` arguments (the caller keeps them alive until the message is written).
#pragma once

#include <cstdint>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc_ros2/msg_types.hpp"

namespace fnmpc::ros2 {

// Topics relative to a vehicle's namespace (/<vehicle>/...), and their QoS (docs/ros2.md).
namespace topics {
inline constexpr const char* kMocapPose = "mocap/pose";      // geometry_msgs/PoseStamped
inline constexpr const char* kImu = "imu";                   // sensor_msgs/Imu
inline constexpr const char* kOpticalFlow = "optical_flow";  // fnmpc_msgs/OpticalFlow
inline constexpr const char* kCompass = "compass";           // fnmpc_msgs/Heading
inline constexpr const char* kBattery = "battery";           // sensor_msgs/BatteryState
inline constexpr const char* kRelative = "relative";         // fnmpc_msgs/RelativeObservation
inline constexpr const char* kSync = "sim/sync";             // fnmpc_msgs/SimSync
inline constexpr const char* kGroundTruth = "ground_truth";  // nav_msgs/Odometry (sim only)
inline constexpr const char* kSetpoint = "setpoint";         // fnmpc_msgs/AttitudeThrustSetpoint
inline constexpr const char* kOdom = "odom";                 // nav_msgs/Odometry: the estimate
inline constexpr const char* kStatus = "status";             // fnmpc_msgs/ControllerStatus
inline constexpr const char* kWaypoint = "waypoint";         // geometry_msgs/PoseStamped (leader)
}  // namespace topics

inline constexpr const char* kWorldFrame = "world";

geometry_msgs_msg_dds__Quaternion_ EulerToQuaternion(const Vec3& euler);
Vec3 QuaternionToEuler(const geometry_msgs_msg_dds__Quaternion_& q);

// ---- Sensor measurements (simulator -> vehicle).
geometry_msgs_msg_dds__PoseStamped_ ToPose(const Measurement& m);
sensor_msgs_msg_dds__Imu_ ToImu(const Measurement& m, const char* body_frame);
fnmpc_msgs_msg_dds__OpticalFlow_ ToOpticalFlow(const Measurement& m);
fnmpc_msgs_msg_dds__Heading_ ToHeading(const Measurement& m);
sensor_msgs_msg_dds__BatteryState_ ToBattery(const Measurement& m);
fnmpc_msgs_msg_dds__RelativeObservation_ ToRelative(const Measurement& m, const char* body_frame);

// ---- Back to fnmpc::Measurement; `vehicle` is the receiving vehicle's index.
Measurement FromPose(const geometry_msgs_msg_dds__PoseStamped_& msg, int vehicle);
Measurement FromImu(const sensor_msgs_msg_dds__Imu_& msg, int vehicle);
Measurement FromOpticalFlow(const fnmpc_msgs_msg_dds__OpticalFlow_& msg, int vehicle);
Measurement FromHeading(const fnmpc_msgs_msg_dds__Heading_& msg, int vehicle);
Measurement FromBattery(const sensor_msgs_msg_dds__BatteryState_& msg, int vehicle);
Measurement FromRelative(const fnmpc_msgs_msg_dds__RelativeObservation_& msg, int vehicle);

// ---- Vehicle outputs. The phase string is a static literal of formation::ToString.
fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_ ToSetpoint(const formation::ControlOutput& out);
// State as nav_msgs/Odometry: pose in `frame`, twist in the body frame (ROS convention).
nav_msgs_msg_dds__Odometry_ ToOdometry(double t, const char* frame, const char* body_frame,
                                       const Vec3& position, const Vec3& velocity_world,
                                       const Vec3& euler, const Vec3& body_rates);
// Inverse of ToOdometry: world-axes velocity from the body-frame twist.
void FromOdometry(const nav_msgs_msg_dds__Odometry_& msg, Vec3* position, Vec3* velocity_world,
                  Vec3* euler);

}  // namespace fnmpc::ros2

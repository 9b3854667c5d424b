// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Odometry.h>
#include <ros/node_handle.h>
#include <ros/time.h>
#include <sensor_msgs/BatteryState.h>
#include <sensor_msgs/Imu.h>

#include <string>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc_ros/AttitudeThrustSetpoint.h"
#include "fnmpc_ros/Heading.h"
#include "fnmpc_ros/OpticalFlow.h"
#include "fnmpc_ros/Plan.h"
#include "fnmpc_ros/RelativeMeasurement.h"
#include "fnmpc_ros/SolverDiagnostics.h"

/// Conversions between fnmpc's value types and ROS messages, and the topic names of the
/// package (docs/ros.md). Pure functions: no node logic lives here.
/// Frames: world ENU z up ("world"); body FLU (x forward, y left, z up, "<vehicle>/base_link");
/// Euler ZYX (roll, pitch, yaw) as in fnmpc/core/rotation.hpp; SI units.
namespace fnmpc::ros_bridge {

/// Topics relative to a vehicle's namespace (/<vehicle>/...).
namespace topics {
inline constexpr const char* kMocapPose = "mocap/pose";      // geometry_msgs/PoseStamped
inline constexpr const char* kImu = "imu";                   // sensor_msgs/Imu
inline constexpr const char* kOpticalFlow = "optical_flow";  // fnmpc_ros/OpticalFlow
inline constexpr const char* kCompass = "compass";           // fnmpc_ros/Heading
inline constexpr const char* kBattery = "battery";           // sensor_msgs/BatteryState
inline constexpr const char* kRelative = "relative";         // fnmpc_ros/RelativeMeasurement
inline constexpr const char* kSync = "sim/sync";             // fnmpc_ros/SimSync
inline constexpr const char* kGroundTruth = "ground_truth";  // nav_msgs/Odometry (sim only)
inline constexpr const char* kTrueBattery = "ground_truth/battery";  // sensor_msgs/BatteryState
inline constexpr const char* kSetpoint = "setpoint";             // fnmpc_ros/AttitudeThrustSetpoint
inline constexpr const char* kEstimate = "estimate";             // nav_msgs/Odometry
inline constexpr const char* kPredictedPath = "predicted_path";  // nav_msgs/Path
inline constexpr const char* kDiagnostics = "diagnostics";       // fnmpc_ros/SolverDiagnostics
inline constexpr const char* kPlan = "plan";  // fnmpc_ros/Plan (cooperative mode)
}  // namespace topics

inline constexpr const char* kWorldFrame = "world";
std::string BodyFrame(const std::string& vehicle);
/// A follower's MPC inertial frame {m}: world axes, origin at its start position.
std::string MpcFrame(const std::string& vehicle);

double ToSec(const ros::Time& t);
/// Simulated time -> ROS time, rounded to the nanosecond (ros::Time cannot be negative).
ros::Time ToRosTime(double t);

geometry_msgs::Quaternion EulerToQuaternion(const Vec3& euler);
Vec3 QuaternionToEuler(const geometry_msgs::Quaternion& q);

// ---- Sensor measurements (sim -> vehicle). `seq` goes into header.seq for information only:
// roscpp overwrites header.seq with its per-publisher counter, so it cannot order messages
// of different topics; lockstep orders them with SimSync::order (docs/ros.md).
geometry_msgs::PoseStamped ToPose(const Measurement& m, std::uint32_t seq);
sensor_msgs::Imu ToImu(const Measurement& m, const std::string& vehicle, std::uint32_t seq);
fnmpc_ros::OpticalFlow ToOpticalFlow(const Measurement& m, std::uint32_t seq);
fnmpc_ros::Heading ToHeading(const Measurement& m, std::uint32_t seq);
sensor_msgs::BatteryState ToBattery(const Measurement& m, std::uint32_t seq);
fnmpc_ros::RelativeMeasurement ToRelative(const Measurement& m, const std::string& vehicle,
                                          std::uint32_t seq);

// ---- Back to fnmpc::Measurement (vehicle side); `vehicle` is the receiving vehicle's index.
Measurement FromPose(const geometry_msgs::PoseStamped& msg, int vehicle);
Measurement FromImu(const sensor_msgs::Imu& msg, int vehicle);
Measurement FromOpticalFlow(const fnmpc_ros::OpticalFlow& msg, int vehicle);
Measurement FromHeading(const fnmpc_ros::Heading& msg, int vehicle);
Measurement FromBattery(const sensor_msgs::BatteryState& msg, int vehicle);
Measurement FromRelative(const fnmpc_ros::RelativeMeasurement& msg, int vehicle);

// ---- Vehicle outputs.
fnmpc_ros::AttitudeThrustSetpoint ToSetpoint(const formation::ControlOutput& out);
fnmpc_ros::SolverDiagnostics ToDiagnostics(const formation::ControlOutput& out,
                                           const formation::VehicleController& controller);
/// Cooperative mode: a plan to its message and back (FromPlan: false on a malformed one,
/// different array lengths or more points than formation::kMaxPlanIntervals + 1).
fnmpc_ros::Plan ToPlan(const formation::PlanMessage& plan);
bool FromPlan(const fnmpc_ros::Plan& msg, formation::PlanMessage* plan);
/// State as nav_msgs/Odometry: pose in `frame`, twist in the body frame (ROS convention).
nav_msgs::Odometry ToOdometry(double t, const std::string& frame, const std::string& vehicle,
                              const Vec3& position, const Vec3& velocity_world, const Vec3& euler,
                              const Vec3& body_rates);
/// Inverse of ToOdometry: world-axes velocity from the body-frame twist.
void FromOdometry(const nav_msgs::Odometry& msg, Vec3* position, Vec3* velocity_world, Vec3* euler);

/// Reads a required private parameter; throws std::runtime_error naming it when missing.
std::string RequiredParam(const ros::NodeHandle& nh, const std::string& name);

}  // namespace fnmpc::ros_bridge

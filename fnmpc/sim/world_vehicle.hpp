// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/model/vehicle_params.hpp"
#include "fnmpc/sim/battery.hpp"
#include "fnmpc/sim/world.hpp"

/// Internals of sim::World shared by its files (world.cpp: the facade, MuJoCo and stepping;
/// autopilot_model.cpp, sensor_sampling.cpp, aero_pass.cpp, battery.cpp): the per-vehicle
/// state and the kinematics the models read. Not part of the API.
namespace fnmpc::sim::detail {

inline constexpr double kRpmToRadPerSec = 2.0 * M_PI / 60.0;
inline constexpr double kTimeEps = 1e-9;  // [s] tolerance of the sample schedules

/// Shortest text that reads back to exactly v.
std::string ShortestText(double v);

/// Rotation (body to world) of MuJoCo's attitude quaternion (w, x, y, z), normalised.
/// The models that read only a few of its entries (Euler angles, the thrust axis) call this
/// where they use it rather than reading Kinematics::rotation: the compiler then contracts
/// the same products into FMAs as where the world read its MuJoCo data directly, which keeps
/// results bit for bit (the build uses x86-64-v3 with GCC's default -ffp-contract=fast).
inline Mat3 QuaternionRotation(const Eigen::Vector4d& q) {
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
}

/// A vehicle's state as MuJoCo holds it at the start of a step (world frame; rates in the
/// body frame; rotation body to world, from the quaternion).
struct Kinematics {
  Vec3 position = Vec3::Zero();
  Vec3 velocity = Vec3::Zero();
  Vec3 rates = Vec3::Zero();
  Mat3 rotation = Mat3::Identity();
  Eigen::Vector4d quaternion{1.0, 0.0, 0.0, 0.0};  // (w, x, y, z), as MuJoCo's qpos
};

/// Per-vehicle simulation state (workspace).
struct Vehicle {
  model::VehicleParams params;
  SensorsConfig sensors;
  int body = -1, qpos = -1, qvel = -1;
  std::array<Vec3, 4> rotor_b;   // rotor centres, body frame [m]
  std::array<double, 4> spin{};  // +1 CCW, -1 CW (seen from above)
  Eigen::Matrix4d mix_inv;       // [T, tau_x, tau_y, tau_z] -> rotor thrusts
  double motor_alpha = 0.0;      // exact discretisation of the motor lag over one step
  double hover_rpm = 1.0;        // rotor speed of hover, m g = 4 T_k rpm^2 [rpm]
  bool direct = false;
  AttitudeCommand command;
  Vec4 throttle = Vec4::Zero();
  Vec4 rpm = Vec4::Zero();
  Vec4 rpm_target = Vec4::Zero();
  Vec4 thrust_guess = Vec4::Constant(3.0);
  double fmax_guess = 10.0;
  double collective_guess = 3.0;  // warm start of the collective-throttle inverse [N]
  BatteryState battery;
  Vec3 v_prev = Vec3::Zero();
  Vec3 p_prev = Vec3::Zero();  // position before the last physics step (instability report)
  Vec3 accel = Vec3::Zero();
  Vec3 aero_force = Vec3::Zero(), aero_torque = Vec3::Zero();
  // This step's total wrench at the centre of mass, world frame (propulsion + aerodynamics).
  Vec3 force_w = Vec3::Zero(), torque_w = Vec3::Zero();
  Vec3 com_b = Vec3::Zero();  // centre of mass from the body origin, body frame (body_ipos)
  AutopilotStatus status;
  double failsafe_yaw = 0.0;  // yaw held by the command-timeout failsafe [rad]
  double land_timer = 0.0;    // land detector: time with the conditions met [s]
  std::array<std::int64_t, kNumSensorKinds> sample_index{};
  // Sensor reality (SensorRealitySettings): biases, burst state, own stream, attitude estimate.
  Vec3 accel_bias = Vec3::Zero(), gyro_bias = Vec3::Zero();
  std::array<bool, kNumSensorKinds> in_burst{};
  std::mt19937_64 reality_rng;
  std::normal_distribution<double> reality_normal{0.0, 1.0};
  std::uniform_real_distribution<double> reality_uniform{0.0, 1.0};
  Mat3 attitude_estimate = Mat3::Identity();
  Vec3 autopilot_gyro = Vec3::Zero();  // the autopilot's own gyro reading [rad/s]
  std::mt19937_64 rng;
  std::normal_distribution<double> normal{0.0, 1.0};
  std::uniform_real_distribution<double> uniform{0.0, 1.0};
  std::vector<int> near;             // relative-sensor candidates (scratch)
  std::vector<Measurement> samples;  // this step's measurements, generation order (scratch)
};

}  // namespace fnmpc::sim::detail

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/eigen_abi.hpp"
#include <array>
#include <string_view>

#include "fnmpc/core/types.hpp"

/// Sensor measurements and sensor settings shared by the simulator (producer), the
/// estimators and the ROS nodes (consumers). Plain value types: no heap, NaN = unset.
///
/// Frames: the world frame {n} is ENU with z up. Each vehicle's MPC inertial frame {m}
/// has the axes of {n} (compasses agree) and its origin at the vehicle's start position.
/// Euler angles are ZYX (roll phi, pitch theta, yaw psi), R = Rz(psi) Ry(theta) Rx(phi).
namespace fnmpc {

enum class SensorKind : int {
  kMocapPose = 0,    ///< motion-capture position [m] and Euler attitude [rad], world frame
  kImu = 1,          ///< accelerometer specific force [m/s^2] and gyro rate [rad/s], body frame
  kOpticalFlow = 2,  ///< velocity [m/s] in the world frame (the reference work emulates it by mocap)
  kCompass = 3,      ///< yaw [rad]
  kBattery = 4,      ///< battery voltage [V]
  kRelative = 5,     ///< range/bearing/elevation/relative yaw of one neighbour (see below)
};
inline constexpr int kNumSensorKinds = 6;

constexpr std::string_view ToString(SensorKind k) {
  constexpr std::array<std::string_view, kNumSensorKinds> kNames{
      "mocap", "imu", "optical_flow", "compass", "battery", "relative"};
  return kNames[static_cast<int>(k)];
}

/// Relative observation of neighbour `target` by the observing vehicle. With
/// d_B = R_obs^T (p_target - p_obs) the offset in the observer's body frame:
/// range = |d_B|, bearing = atan2(d_B.y, d_B.x), elevation = asin(d_B.z / range),
/// relative_yaw = wrap(psi_target - psi_obs).
struct RelativeObservation {
  int target = -1;            ///< index of the observed vehicle
  double range = kNaN;        ///< [m]
  double bearing = kNaN;      ///< [rad]
  double elevation = kNaN;    ///< [rad]
  double relative_yaw = kNaN; ///< [rad]
};

/// One time-stamped measurement. Only the fields of its kind are set; the others are NaN.
struct Measurement {
  SensorKind kind = SensorKind::kMocapPose;
  int vehicle = -1;        ///< index of the vehicle carrying the sensor
  double stamp = kNaN;     ///< time of validity [s]
  double arrival = kNaN;   ///< time of delivery = stamp + latency [s]
  Vec3 position = Vec3::Constant(kNaN);  ///< kMocapPose [m]
  Vec3 euler = Vec3::Constant(kNaN);     ///< kMocapPose (roll, pitch, yaw) [rad]
  Vec3 accel = Vec3::Constant(kNaN);     ///< kImu specific force, body [m/s^2]
  Vec3 gyro = Vec3::Constant(kNaN);      ///< kImu angular rate, body [rad/s]
  Vec3 velocity = Vec3::Constant(kNaN);  ///< kOpticalFlow [m/s]
  double yaw = kNaN;                     ///< kCompass [rad]
  double voltage = kNaN;                 ///< kBattery [V]
  RelativeObservation relative;          ///< kRelative
};

/// Rate, latency, noise and dropout of one sensor.
struct SensorSpec {
  bool enabled = true;
  double rate_hz = 0.0;         ///< sampling rate [Hz], > 0 when enabled
  double latency_s = 0.0;       ///< delivery delay [s], >= 0
  double dropout_probability = 0.0;  ///< chance that one sample is lost, in [0, 1)
  /// White-noise standard deviation per channel, in the kind's units; meaning per kind:
  /// mocap (pos x3 [m]), imu accel x3 [m/s^2], optical flow x3 [m/s], compass [rad] in [0],
  /// battery [V] in [0], relative: range [m] in [0], bearing/elevation [rad] in [1],[2].
  Vec3 noise = Vec3::Zero();
  /// Second noise channel: mocap attitude [rad], imu gyro [rad/s], relative yaw [rad] in [0].
  Vec3 noise2 = Vec3::Zero();
  /// Relative sensor only: range noise grows as noise * (1 + range_noise_growth * range).
  double range_noise_growth = 0.0;  ///< [1/m]
  double max_range = kInf;          ///< relative sensor only [m]
  double field_of_view = 2 * 3.141592653589793;  ///< relative sensor only, full cone angle [rad]
};

/// Settings of every sensor of one vehicle (the sensors YAML).
struct SensorsConfig {
  SensorSpec mocap{true, 60.0, 0.005, 0.0, Vec3::Constant(0.001), Vec3::Constant(0.002)};
  SensorSpec imu{true, 250.0, 0.002, 0.0, Vec3::Constant(0.05), Vec3::Constant(0.005)};
  SensorSpec optical_flow{true, 30.0, 0.01, 0.0, Vec3::Constant(0.02), Vec3::Zero()};
  SensorSpec compass{true, 50.0, 0.005, 0.0, Vec3(0.01, 0, 0), Vec3::Zero()};
  SensorSpec battery{true, 10.0, 0.0, 0.0, Vec3(0.02, 0, 0), Vec3::Zero()};
  SensorSpec relative{true, 50.0, 0.01, 0.0, Vec3(0.02, 0.01, 0.01), Vec3(0.02, 0, 0), 0.05,
                      8.0, 2 * 3.141592653589793};
};

}  // namespace fnmpc

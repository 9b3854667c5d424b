// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/eigen_abi.hpp"  // before any Eigen header

#include <array>
#include <string_view>

#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"

/// Sensor measurements and sensor settings shared by the simulator (producer), the
/// estimators and the ROS nodes (consumers). Plain value types: no heap, NaN = unset.
///
/// Frames: the world frame {n} is ENU with z up. Each vehicle's MPC inertial frame {m}
/// has the axes of {n} (compasses agree) and its origin at the vehicle's start position.
/// Euler angles are ZYX (roll phi, pitch theta, yaw psi), R = Rz(psi) Ry(theta) Rx(phi).
namespace fnmpc {

enum class SensorKind : int {
  kMocapPose = 0,  ///< motion-capture position [m] and Euler attitude [rad], world frame
  kImu = 1,        ///< accelerometer specific force [m/s^2] and gyro rate [rad/s], body frame
  kOpticalFlow =
      2,          ///< velocity [m/s] in the world frame (the reference work emulates it by mocap)
  kCompass = 3,   ///< yaw [rad]
  kBattery = 4,   ///< battery voltage [V]
  kRelative = 5,  ///< range/bearing/elevation/relative yaw of one neighbour (see below)
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
  int target = -1;             ///< index of the observed vehicle
  double range = kNaN;         ///< [m]
  double bearing = kNaN;       ///< [rad]
  double elevation = kNaN;     ///< [rad]
  double relative_yaw = kNaN;  ///< [rad]
};

/// One time-stamped measurement. Only the fields of its kind are set; the others are NaN.
struct Measurement {
  SensorKind kind = SensorKind::kMocapPose;
  int vehicle = -1;                      ///< index of the vehicle carrying the sensor
  double stamp = kNaN;                   ///< time of validity [s]
  double arrival = kNaN;                 ///< time of delivery = stamp + latency [s]
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
  double rate_hz = 0.0;              ///< sampling rate [Hz], > 0 when enabled
  double latency_s = 0.0;            ///< delivery delay [s], >= 0
  double dropout_probability = 0.0;  ///< chance that one sample is lost, in [0, 1)
  /// White-noise standard deviation per channel, in the kind's units; meaning per kind:
  /// mocap (pos x3 [m]), imu accel x3 [m/s^2], optical flow x3 [m/s], compass [rad] in [0],
  /// battery [V] in [0], relative: range [m] in [0], bearing/elevation [rad] in [1],[2].
  Vec3 noise = Vec3::Zero();
  /// Second noise channel: mocap attitude [rad], imu gyro [rad/s], relative yaw [rad] in [0].
  Vec3 noise2 = Vec3::Zero();
  /// Relative sensor only: range noise grows as noise * (1 + range_noise_growth * range).
  double range_noise_growth = 0.0;               ///< [1/m]
  double max_range = kInf;                       ///< relative sensor only [m]
  double field_of_view = 2 * 3.141592653589793;  ///< relative sensor only, full cone angle [rad]

  /// The keys every sensor shares (the sensors file, below the sensor's name); the noise keys
  /// are each kind's own (SensorsConfig::Serialize). rate_hz is checked only when enabled.
  template <class Archive>
  void SerializeCommon(Archive* a) {
    a->Visit("enabled", &enabled, AnyValue(), "false: the sensor delivers nothing");
    a->Visit("rate_hz", &rate_hz, AnyValue(),
             "[Hz] sampling rate; when enabled > 0 and ≤ 1000 (the simulator samples once per "
             "1 ms physics step)");
    a->Visit("latency_s", &latency_s, NonNegative().AtMost(10.0, "s"), "[s] delivery delay");
    a->Visit("dropout_probability", &dropout_probability, NonNegative().Below(1.0, ""),
             "chance that one sample is lost");
  }
};

/// Settings of every sensor of one vehicle (the sensors YAML).
struct SensorsConfig {
  SensorSpec mocap{true, 60.0, 0.005, 0.0, Vec3::Constant(0.001), Vec3::Constant(0.002)};
  SensorSpec imu{true, 250.0, 0.002, 0.0, Vec3::Constant(0.05), Vec3::Constant(0.005)};
  SensorSpec optical_flow{true, 30.0, 0.01, 0.0, Vec3::Constant(0.02), Vec3::Zero()};
  SensorSpec compass{true, 50.0, 0.005, 0.0, Vec3(0.01, 0, 0), Vec3::Zero()};
  SensorSpec battery{true, 10.0, 0.0, 0.0, Vec3(0.02, 0, 0), Vec3::Zero()};
  SensorSpec relative{true,
                      50.0,
                      0.01,
                      0.0,
                      Vec3(0.02, 0.01, 0.01),
                      Vec3(0.02, 0, 0),
                      0.05,
                      8.0,
                      2 * 3.141592653589793};

  /// Every key of the sensors file (config/sensors/default.yaml) with its accepted values and
  /// meaning. Noise standard deviations are > 0: the estimators divide by them.
  template <class Archive>
  void Serialize(Archive* a) {
    auto mocap_keys = Fields([this](auto* s) {
      mocap.SerializeCommon(s);
      s->Visit("position_noise", &mocap.noise, Positive(), "[m] white noise sd per axis");
      s->Visit("attitude_noise", &mocap.noise2, Positive(), "[rad] roll, pitch, yaw");
    });
    auto imu_keys = Fields([this](auto* s) {
      imu.SerializeCommon(s);
      s->Visit("accel_noise", &imu.noise, Positive(), "[m/s²] specific force, body frame");
      s->Visit("gyro_noise", &imu.noise2, Positive(), "[rad/s] angular rate, body frame");
    });
    auto flow_keys = Fields([this](auto* s) {
      optical_flow.SerializeCommon(s);
      s->Visit("velocity_noise", &optical_flow.noise, Positive(), "[m/s] world frame");
    });
    auto compass_keys = Fields([this](auto* s) {
      compass.SerializeCommon(s);
      s->Visit("yaw_noise", &compass.noise.x(), Positive(), "[rad]");
    });
    auto battery_keys = Fields([this](auto* s) {
      battery.SerializeCommon(s);
      s->Visit("voltage_noise", &battery.noise.x(), NonNegative(), "[V]");
    });
    auto relative_keys = Fields([this](auto* s) {
      relative.SerializeCommon(s);
      s->Visit("range_noise", &relative.noise.x(), Positive(), "[m] at zero range");
      s->Visit("range_noise_growth", &relative.range_noise_growth, NonNegative(),
               "[1/m] range sd = range_noise (1 + growth × range)");
      s->Visit("bearing_noise", &relative.noise.y(), Positive(), "[rad]");
      s->Visit("elevation_noise", &relative.noise.z(), Positive(), "[rad]");
      s->Visit("relative_yaw_noise", &relative.noise2.x(), Positive(), "[rad]");
      s->Visit("max_range", &relative.max_range, Positive(), "[m] neighbours farther are not seen");
      s->Visit("field_of_view", &relative.field_of_view, Positive(),
               "[rad] full cone angle about body x (2π: all round)");
    });
    a->Nested("mocap", &mocap_keys);
    a->Nested("imu", &imu_keys);
    a->Nested("optical_flow", &flow_keys);
    a->Nested("compass", &compass_keys);
    a->Nested("battery", &battery_keys);
    a->Nested("relative", &relative_keys);
  }
};

}  // namespace fnmpc

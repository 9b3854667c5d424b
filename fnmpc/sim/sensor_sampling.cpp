// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/sensor_sampling.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "fnmpc/core/relative_sensor.hpp"
#include "fnmpc/core/rotation.hpp"

namespace fnmpc::sim::detail {

namespace {

const SensorSpec& SpecOf(const SensorsConfig& c, int kind) {
  switch (static_cast<SensorKind>(kind)) {
    case SensorKind::kMocapPose:
      return c.mocap;
    case SensorKind::kImu:
      return c.imu;
    case SensorKind::kOpticalFlow:
      return c.optical_flow;
    case SensorKind::kCompass:
      return c.compass;
    case SensorKind::kBattery:
      return c.battery;
    case SensorKind::kRelative:
      break;
  }
  return c.relative;
}

}  // namespace

bool RelativeSampleDue(const Vehicle& v, double t) {
  const SensorSpec& s = v.sensors.relative;
  const std::int64_t idx = v.sample_index[static_cast<int>(SensorKind::kRelative)];
  return s.enabled && !(t + kTimeEps < static_cast<double>(idx) / s.rate_hz);
}

void UpdateSensorReality(const WorldConfig& config, const Kinematics& kin, Vehicle& v) {
  const SensorRealitySettings& sr = config.sensor_reality;
  const double dt = 1.0 / config.autopilot_rate_hz;
  auto gauss3 = [&v]() {
    return Vec3(v.reality_normal(v.reality_rng), v.reality_normal(v.reality_rng),
                v.reality_normal(v.reality_rng));
  };
  v.accel_bias += sr.accel_bias_walk * std::sqrt(dt) * gauss3();
  v.gyro_bias += sr.gyro_bias_walk * std::sqrt(dt) * gauss3();
  if (!sr.autopilot_estimate) return;
  const Vec3 gyro_noise = v.sensors.imu.enabled ? v.sensors.imu.noise2 : Vec3::Zero();
  v.autopilot_gyro = kin.rates + v.gyro_bias + gyro_noise.cwiseProduct(gauss3());
  // External attitude (mocap-like noise), error in the body frame of the estimate.
  const Vec3 att_noise = v.sensors.mocap.enabled ? v.sensors.mocap.noise2 : Vec3::Zero();
  const Vec3 e_true =
      EulerZyx(QuaternionRotation(kin.quaternion)) + att_noise.cwiseProduct(gauss3());
  const Mat3 r_meas = RotationZyx(e_true.x(), e_true.y(), e_true.z());
  const Mat3 m = v.attitude_estimate.transpose() * r_meas;
  const Vec3 err(0.5 * (m(2, 1) - m(1, 2)), 0.5 * (m(0, 2) - m(2, 0)), 0.5 * (m(1, 0) - m(0, 1)));
  const Vec3 omega = v.autopilot_gyro + err / sr.estimate_time_constant;
  const double angle = omega.norm() * dt;
  if (angle > 0.0) {
    v.attitude_estimate =
        v.attitude_estimate * Eigen::AngleAxisd(angle, omega.normalized()).toRotationMatrix();
  }
  // Re-orthonormalise.
  v.attitude_estimate = Eigen::Quaterniond(v.attitude_estimate).normalized().toRotationMatrix();
}

void SampleSensors(const WorldConfig& config, int vi, double t, const std::vector<Kinematics>& kin,
                   const RelativeIndex& index, Vehicle& v, std::vector<Measurement>* out) {
  out->clear();
  const int n = static_cast<int>(kin.size());
  for (int kind = 0; kind < kNumSensorKinds; ++kind) {
    const SensorSpec& s = SpecOf(v.sensors, kind);
    if (!s.enabled) continue;
    std::int64_t& idx = v.sample_index[kind];
    if (t + kTimeEps < static_cast<double>(idx) / s.rate_hz) continue;
    // The next sample index after t in O(1) whatever the rate (a rate above the physics
    // rate samples once per step); the loop only corrects the rounding of the product.
    idx = std::max(idx + 1, static_cast<std::int64_t>(std::floor((t + kTimeEps) * s.rate_hz)) + 1);
    while (static_cast<double>(idx) / s.rate_hz <= t + kTimeEps) ++idx;
    const Mat3 rot_wb = kin[vi].rotation;
    Measurement meas;
    meas.kind = static_cast<SensorKind>(kind);
    meas.vehicle = vi;
    meas.stamp = t;
    meas.arrival = t + s.latency_s;
    const SensorRealitySettings& sr = config.sensor_reality;
    if (sr.enabled) {
      meas.arrival += sr.latency_jitter * v.reality_uniform(v.reality_rng);
      // Bursts hit the radio-linked streams only (motion capture and the relative sensor's
      // link); the IMU, flow, compass and battery are wired on board.
      // Gilbert-Elliott: p(enter) = share / length, p(leave) = 1 / length (per sample).
      const bool radio = meas.kind == SensorKind::kMocapPose || meas.kind == SensorKind::kRelative;
      const double samples = std::max(1.0, sr.burst_length * s.rate_hz);
      const double leave = 1.0 / samples;
      const double enter = sr.burst_share / (1.0 - sr.burst_share) * leave;
      bool& burst = v.in_burst[kind];
      if (radio) {
        const double u = v.reality_uniform(v.reality_rng);
        burst = burst ? u >= leave : u < enter;
      }
      if (burst) continue;
    }
    auto noise3 = [&](const Vec3& sd) {
      return Vec3(sd.x() * v.normal(v.rng), sd.y() * v.normal(v.rng), sd.z() * v.normal(v.rng));
    };
    if (meas.kind == SensorKind::kRelative) {
      const Vec3 p_obs = kin[vi].position;
      const double yaw_obs = EulerZyx(rot_wb).z();
      // Every vehicle in ascending index order, or the cell list's candidates (ascending, a
      // superset of those within max_range): the same draws in the same order.
      const bool indexed = index.cells != nullptr && s.max_range <= index.side && p_obs.allFinite();
      if (indexed) {
        // The body-frame range equals the world distance up to rounding: a small margin.
        index.cells->Near(p_obs, s.max_range * (1.0 + 1e-9) + 1e-9, &v.near);
      }
      const int count = indexed ? static_cast<int>(v.near.size()) : n;
      for (int k = 0; k < count; ++k) {
        const int j = indexed ? v.near[static_cast<std::size_t>(k)] : k;
        if (j == vi) continue;
        if (ObserveRelative(s, rot_wb, p_obs, yaw_obs, j, kin[j].position,
                            EulerZyx(kin[j].rotation).z(), v.rng, v.uniform, v.normal,
                            &meas.relative)) {
          out->push_back(meas);
        }
      }
      continue;
    }
    if (v.uniform(v.rng) < s.dropout_probability) continue;
    switch (meas.kind) {
      case SensorKind::kMocapPose: {
        meas.position = kin[vi].position + noise3(s.noise);
        if (sr.enabled && v.reality_uniform(v.reality_rng) < sr.mocap_outlier_rate) {
          const Vec3 u(v.reality_normal(v.reality_rng), v.reality_normal(v.reality_rng),
                       v.reality_normal(v.reality_rng));
          meas.position += sr.mocap_outlier_size * u.normalized();
        }
        Vec3 e = EulerZyx(rot_wb) + noise3(s.noise2);
        e.z() = WrapAngle(e.z());
        meas.euler = e;
        break;
      }
      case SensorKind::kImu: {
        const Vec3 g(0.0, 0.0, -config.gravity);
        meas.accel = rot_wb.transpose() * (v.accel - g) + noise3(s.noise);
        meas.gyro = kin[vi].rates + noise3(s.noise2);
        if (sr.enabled) {
          meas.accel += v.accel_bias;
          meas.gyro += v.gyro_bias;
        }
        break;
      }
      case SensorKind::kOpticalFlow:
        meas.velocity = kin[vi].velocity + noise3(s.noise);
        break;
      case SensorKind::kCompass:
        meas.yaw = WrapAngle(EulerZyx(rot_wb).z() + s.noise.x() * v.normal(v.rng));
        break;
      case SensorKind::kBattery:
        meas.voltage = v.battery.voltage + s.noise.x() * v.normal(v.rng);
        break;
      case SensorKind::kRelative:
        break;
    }
    out->push_back(meas);
  }
}

}  // namespace fnmpc::sim::detail

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/sensors_yaml.hpp"

namespace fnmpc::config {

namespace {

double NonNegative(YamlMap& m, const std::string& key, double fallback) {
  const double v = m.Double(key, fallback);
  if (v < 0.0) throw m.ErrorAt(key, "must be >= 0, got " + std::to_string(v));
  return v;
}

/// A noise standard deviation the estimators divide by: > 0 (they reject 0 later, without
/// the file's name, so it is checked here).
Eigen::Vector3d Noise3(YamlMap& m, const std::string& key, const Eigen::Vector3d& fallback) {
  const Eigen::Vector3d v = m.Vector3(key, fallback);
  if (!(v.array() > 0.0).all()) {
    throw m.ErrorAt(key, "noise standard deviations must be > 0 (the estimators divide by them)");
  }
  return v;
}

double Noise(YamlMap& m, const std::string& key, double fallback) {
  const double v = m.Double(key, fallback);
  if (!(v > 0.0)) {
    throw m.ErrorAt(key,
                    "noise standard deviation must be > 0 (the estimators divide by it), got " +
                        std::to_string(v));
  }
  return v;
}

/// Keys shared by every sensor; the per-kind noise keys are read by the caller.
void ReadCommon(YamlMap& m, SensorSpec* s) {
  s->enabled = m.Bool("enabled", s->enabled);
  s->rate_hz = m.Double("rate_hz", s->rate_hz);
  if (s->enabled && !(s->rate_hz > 0.0 && s->rate_hz <= kMaxSensorRateHz)) {
    throw m.ErrorAt("rate_hz",
                    "must be > 0 and <= " + std::to_string(static_cast<int>(kMaxSensorRateHz)) +
                        " Hz (the physics rate), got " + std::to_string(s->rate_hz));
  }
  s->latency_s = NonNegative(m, "latency_s", s->latency_s);
  if (s->latency_s > 10.0) throw m.ErrorAt("latency_s", "must be <= 10 s");
  s->dropout_probability = m.Double("dropout_probability", s->dropout_probability);
  if (!(s->dropout_probability >= 0.0 && s->dropout_probability < 1.0)) {
    throw m.ErrorAt("dropout_probability",
                    "must be in [0, 1), got " + std::to_string(s->dropout_probability));
  }
}

double Scalar(YamlMap& m, const std::string& key, double fallback) {
  return NonNegative(m, key, fallback);
}

}  // namespace

SensorsConfig ParseSensors(YamlMap map) {
  SensorsConfig c;
  if (map.Has("mocap")) {
    YamlMap m = map.Map("mocap");
    ReadCommon(m, &c.mocap);
    c.mocap.noise = Noise3(m, "position_noise", c.mocap.noise);
    c.mocap.noise2 = Noise3(m, "attitude_noise", c.mocap.noise2);
    m.Finish();
  }
  if (map.Has("imu")) {
    YamlMap m = map.Map("imu");
    ReadCommon(m, &c.imu);
    c.imu.noise = Noise3(m, "accel_noise", c.imu.noise);
    c.imu.noise2 = Noise3(m, "gyro_noise", c.imu.noise2);
    m.Finish();
  }
  if (map.Has("optical_flow")) {
    YamlMap m = map.Map("optical_flow");
    ReadCommon(m, &c.optical_flow);
    c.optical_flow.noise = Noise3(m, "velocity_noise", c.optical_flow.noise);
    m.Finish();
  }
  if (map.Has("compass")) {
    YamlMap m = map.Map("compass");
    ReadCommon(m, &c.compass);
    c.compass.noise.x() = Noise(m, "yaw_noise", c.compass.noise.x());
    m.Finish();
  }
  if (map.Has("battery")) {
    YamlMap m = map.Map("battery");
    ReadCommon(m, &c.battery);
    c.battery.noise.x() = Scalar(m, "voltage_noise", c.battery.noise.x());
    m.Finish();
  }
  if (map.Has("relative")) {
    YamlMap m = map.Map("relative");
    SensorSpec& r = c.relative;
    ReadCommon(m, &r);
    r.noise.x() = Noise(m, "range_noise", r.noise.x());
    r.noise.y() = Noise(m, "bearing_noise", r.noise.y());
    r.noise.z() = Noise(m, "elevation_noise", r.noise.z());
    r.noise2.x() = Noise(m, "relative_yaw_noise", r.noise2.x());
    r.range_noise_growth = Scalar(m, "range_noise_growth", r.range_noise_growth);
    r.max_range = m.Double("max_range", r.max_range);
    if (!(r.max_range > 0.0)) {
      throw m.ErrorAt("max_range", "must be > 0, got " + std::to_string(r.max_range));
    }
    r.field_of_view = m.Double("field_of_view", r.field_of_view);
    if (!(r.field_of_view > 0.0)) {
      throw m.ErrorAt("field_of_view", "must be > 0, got " + std::to_string(r.field_of_view));
    }
    m.Finish();
  }
  map.Finish();
  return c;
}

SensorsConfig LoadSensorsFile(const std::string& path) {
  return ParseSensors(YamlMap::LoadFile(path));
}

}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/world_settings.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <stdexcept>

#include "fnmpc/sim/world_vehicle.hpp"

namespace fnmpc::sim {

namespace detail {

std::string ShortestText(double v) {
  std::array<char, 32> buf{};
  const auto res = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), res.ptr);
}

}  // namespace detail

namespace {

using detail::ShortestText;

void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

void CheckSpec(const SensorSpec& s, const std::string& who, std::string_view name) {
  const std::string ctx = "[World] " + who + " sensor '" + std::string(name) + "': ";
  if (!s.enabled) return;
  Require(s.rate_hz > 0.0 && std::isfinite(s.rate_hz),
          ctx + "rate_hz must be > 0, got " + std::to_string(s.rate_hz));
  Require(s.latency_s >= 0.0 && std::isfinite(s.latency_s),
          ctx + "latency_s must be >= 0, got " + std::to_string(s.latency_s));
  Require(
      s.dropout_probability >= 0.0 && s.dropout_probability < 1.0,
      ctx + "dropout_probability must be in [0, 1), got " + std::to_string(s.dropout_probability));
  Require(s.noise.allFinite() && (s.noise.array() >= 0.0).all() && s.noise2.allFinite() &&
              (s.noise2.array() >= 0.0).all(),
          ctx + "noise standard deviations must be finite and >= 0");
  Require(s.range_noise_growth >= 0.0,
          ctx + "range_noise_growth must be >= 0, got " + std::to_string(s.range_noise_growth));
  Require(s.max_range > 0.0, ctx + "max_range must be > 0, got " + std::to_string(s.max_range));
  Require(s.field_of_view > 0.0,
          ctx + "field_of_view must be > 0, got " + std::to_string(s.field_of_view));
}

}  // namespace

Vec3 DiscreteGustVelocity(const std::vector<DiscreteGust>& gusts, double t) {
  Vec3 v = Vec3::Zero();
  for (const DiscreteGust& g : gusts) {
    const double x = (t - g.start) / g.duration;
    if (x < 0.0 || x > 1.0) continue;
    v += 0.5 * (1.0 - std::cos(2.0 * M_PI * x)) * g.amplitude;
  }
  return v;
}

void ValidateSensors(const SensorsConfig& s, const std::string& who) {
  CheckSpec(s.mocap, who, "mocap");
  CheckSpec(s.imu, who, "imu");
  CheckSpec(s.optical_flow, who, "optical_flow");
  CheckSpec(s.compass, who, "compass");
  CheckSpec(s.battery, who, "battery");
  CheckSpec(s.relative, who, "relative");
}

void SensorRealitySettings::Validate() const {
  for (double x : {accel_bias, gyro_bias, accel_bias_walk, gyro_bias_walk, latency_jitter,
                   mocap_outlier_size}) {
    Require(x >= 0.0 && std::isfinite(x),
            "[World] sensor_reality: biases, walks, jitter and outlier size must be >= 0");
  }
  Require(burst_share >= 0.0 && burst_share < 0.5,
          "[World] sensor_reality.burst_share must be in [0, 0.5)");
  Require(burst_length > 0.0 && std::isfinite(burst_length),
          "[World] sensor_reality.burst_length must be > 0");
  Require(mocap_outlier_rate >= 0.0 && mocap_outlier_rate <= 1.0,
          "[World] sensor_reality.mocap_outlier_rate must be in [0, 1]");
  Require(estimate_time_constant > 0.0 && std::isfinite(estimate_time_constant),
          "[World] sensor_reality.estimate_time_constant must be > 0");
}

void WorldConfig::Validate() const {
  Require(!vehicles.empty(), "[World] at least one vehicle is required");
  Require(physics_dt > 0.0 && physics_dt <= 0.01,
          "[World] physics_dt must be in (0, 0.01] s, got " + std::to_string(physics_dt));
  Require(autopilot_rate_hz > 0.0 && std::isfinite(autopilot_rate_hz),
          "[World] autopilot_rate_hz must be > 0, got " + std::to_string(autopilot_rate_hz));
  Require(motor_time_constant > 0.0,
          "[World] motor_time_constant must be > 0, got " + std::to_string(motor_time_constant));
  Require(gravity >= 0.0 && std::isfinite(gravity),
          "[World] gravity must be >= 0, got " + std::to_string(gravity));
  Require(drag_coefficient.allFinite() && (drag_coefficient.array() >= 0.0).all(),
          "[World] drag_coefficient must be >= 0");
  Require(relative_index_min_vehicles >= 0,
          "[World] relative_index_min_vehicles must be >= 0, got " +
              std::to_string(relative_index_min_vehicles));
  Require(contacts_per_vehicle >= 1 && contacts_per_vehicle <= 1000,
          "[World] contacts_per_vehicle must be in [1, 1000], got " +
              std::to_string(contacts_per_vehicle));
  const BatterySettings& b = battery;
  Require(b.full_voltage > b.empty_voltage && b.empty_voltage > 0.0,
          "[World] battery needs full_voltage > empty_voltage > 0, got " +
              std::to_string(b.full_voltage) + " and " + std::to_string(b.empty_voltage));
  Require(b.capacity_ah > 0.0,
          "[World] battery capacity_ah must be > 0, got " + std::to_string(b.capacity_ah));
  Require(b.internal_resistance >= 0.0, "[World] battery internal_resistance must be >= 0, got " +
                                            std::to_string(b.internal_resistance));
  Require(b.efficiency > 0.0 && b.efficiency <= 1.0,
          "[World] battery efficiency must be in (0, 1], got " + std::to_string(b.efficiency));
  Require(b.initial_soc > 0.0 && b.initial_soc <= 1.0,
          "[World] battery initial_soc must be in (0, 1], got " + std::to_string(b.initial_soc));
  downwash.Validate();
  if (sensor_reality.enabled) sensor_reality.Validate();
  if (reality.wake) reality.wake_turbulence.Validate();
  Require(reality.rotor_drag >= 0.0 && std::isfinite(reality.rotor_drag),
          "[World] reality.rotor_drag must be >= 0");
  Require(reality.blade.radius > 0.0 && reality.blade.solidity > 0.0 &&
              reality.blade.lift_slope > 0.0 && reality.blade.air_density > 0.0,
          "[World] reality.blade needs radius, solidity, lift_slope and air_density > 0");
  Require(wind.velocity.allFinite(), "[World] wind velocity must be finite");
  Require(wind.gust_std >= 0.0,
          "[World] wind gust_std must be >= 0, got " + std::to_string(wind.gust_std));
  Require(wind.gust_time_constant > 0.0, "[World] wind gust_time_constant must be > 0, got " +
                                             std::to_string(wind.gust_time_constant));
  if (wind.turbulence) wind.dryden.Validate();
  for (const DiscreteGust& g : wind.discrete_gusts) {
    Require(std::isfinite(g.start) && g.duration > 0.0 && std::isfinite(g.duration) &&
                g.amplitude.allFinite(),
            "[World] discrete gust needs a finite start, duration > 0 and a finite amplitude");
  }
  {
    const CommandTimeoutSettings& c = command_timeout;
    Require(c.timeout > 0.0 && std::isfinite(c.timeout),
            "[World] command_timeout.timeout must be > 0, got " + std::to_string(c.timeout));
    Require(c.descent_speed > 0.0 && std::isfinite(c.descent_speed),
            "[World] command_timeout.descent_speed must be > 0, got " +
                std::to_string(c.descent_speed));
    Require(c.velocity_gain > 0.0 && std::isfinite(c.velocity_gain),
            "[World] command_timeout.velocity_gain must be > 0, got " +
                std::to_string(c.velocity_gain));
    Require(c.land_speed > 0.0 && std::isfinite(c.land_speed),
            "[World] command_timeout.land_speed must be > 0, got " + std::to_string(c.land_speed));
    Require(c.land_detect_time >= 0.0 && std::isfinite(c.land_detect_time),
            "[World] command_timeout.land_detect_time must be >= 0, got " +
                std::to_string(c.land_detect_time));
  }
  for (std::size_t i = 0; i < vehicles.size(); ++i) {
    const std::string who = "vehicle " + std::to_string(i);
    const VehicleSpec& v = vehicles[i];
    try {
      v.params.Validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("[World] " + who + ": " + e.what());
    }
    Require(v.position.allFinite() && std::isfinite(v.yaw),
            "[World] " + who + ": initial position and yaw must be finite");
    Require(!ground || v.position.z() >= kRestHeight - 1e-3,
            "[World] " + who + ": initial z must be >= World::kRestHeight (" +
                ShortestText(kRestHeight) + " m, resting on the ground), got " +
                ShortestText(v.position.z()));
    Require(std::isnan(v.motor_time_constant) ||
                (v.motor_time_constant > 0.0 && std::isfinite(v.motor_time_constant)),
            "[World] " + who + ": motor_time_constant must be NaN or > 0, got " +
                std::to_string(v.motor_time_constant));
    Require(
        std::isnan(v.initial_throttle) || (v.initial_throttle >= 0.0 && v.initial_throttle <= 1.0),
        "[World] " + who + ": initial_throttle must be NaN or in [0, 1], got " +
            std::to_string(v.initial_throttle));
    ValidateSensors(v.sensors, who);
  }
}

}  // namespace fnmpc::sim

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>
#include <cmath>
#include <random>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"

namespace fnmpc {

/// The relative sensor's model (docs/simulator.md "Sensors"), shared by the simulator
/// (sim::World) and the ground-side bridge (`fnmpc bridge`): the target's offset in the
/// observer's body frame, seen when 0 < range <= max_range and inside the field of view about
/// body x, then dropped with the dropout probability, then range (noise growing with range),
/// bearing, elevation and relative yaw with their noises. Draws, in this order and only as far
/// as it gets: one uniform (dropout), four normals (range, bearing, elevation, yaw); both the
/// simulator and the bridge depend on that order for their streams. Returns false (no
/// observation, *out untouched) when the target is not seen.
inline bool ObserveRelative(const SensorSpec& s, const Mat3& rot_observer, const Vec3& p_observer,
                            double yaw_observer, int target, const Vec3& p_target,
                            double yaw_target, std::mt19937_64& rng,
                            std::uniform_real_distribution<double>& uniform,
                            std::normal_distribution<double>& normal, RelativeObservation* out) {
  const Vec3 d_b = rot_observer.transpose() * (p_target - p_observer);
  const double range = d_b.norm();
  if (range > s.max_range || range <= 0.0) return false;
  if (s.field_of_view < 2.0 * M_PI &&
      std::acos(std::clamp(d_b.x() / range, -1.0, 1.0)) > 0.5 * s.field_of_view) {
    return false;
  }
  if (uniform(rng) < s.dropout_probability) return false;
  RelativeObservation& o = *out;
  o.target = target;
  o.range = range + s.noise.x() * (1.0 + s.range_noise_growth * range) * normal(rng);
  o.bearing = WrapAngle(std::atan2(d_b.y(), d_b.x()) + s.noise.y() * normal(rng));
  o.elevation =
      std::clamp(std::asin(d_b.z() / range) + s.noise.z() * normal(rng), -M_PI / 2, M_PI / 2);
  o.relative_yaw = WrapAngle(yaw_target - yaw_observer + s.noise2.x() * normal(rng));
  return true;
}

}  // namespace fnmpc

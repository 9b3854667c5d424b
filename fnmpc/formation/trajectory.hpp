// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <vector>

#include "fnmpc/core/types.hpp"

namespace fnmpc::formation {

/// Leader reference: quintic rest-to-rest legs between waypoints, each leg followed by a
/// hold. Positions are offsets from an anchor (the leader's hover point when the NMPC
/// engages); time is measured from the start of the first leg. Before the start and after
/// the last hold the reference rests at the first / last point.
class WaypointTrajectory {
 public:
  WaypointTrajectory() = default;
  /// `points[0]` is the start; leg i goes from points[i] to points[i + 1] in
  /// leg_durations[i] [s] and then holds for hold_durations[i] [s]. Throws
  /// std::invalid_argument on mismatched sizes or non-positive leg durations.
  WaypointTrajectory(std::vector<Vec3> points, std::vector<double> leg_durations,
                     std::vector<double> hold_durations);
  /// Same leg and hold duration [s] for every leg.
  static WaypointTrajectory Uniform(std::vector<Vec3> points, double leg_duration,
                                    double hold_duration);
  /// Manually moved leader: `moves` quintic moves to points drawn uniformly in the box
  /// [-size/2, size/2] (per axis, [m]) with durations uniform in [min_leg, max_leg] [s] and
  /// pauses uniform in [min_hold, max_hold] [s], starting at the origin; std::mt19937 seeded
  /// by `seed`. A smooth random walk as when the leader is carried by hand.
  static WaypointTrajectory RandomWalk(const Vec3& size, int moves, double min_leg, double max_leg,
                                       double min_hold, double max_hold, std::uint64_t seed);

  /// Offset [m], velocity [m/s] and acceleration [m/s^2] at time t [s] since the start.
  void Sample(double t, Vec3* p, Vec3* v, Vec3* a = nullptr) const;
  /// 0 while a leg is under way, else the time [s] since the reference stopped (kInf
  /// before the first leg starts).
  [[nodiscard]] double TimeSinceStop(double t) const;
  /// Time at which the last leg ends [s].
  [[nodiscard]] double end_of_motion() const;
  /// Total duration including the last hold [s].
  [[nodiscard]] double duration() const;
  [[nodiscard]] const std::vector<Vec3>& points() const { return points_; }
  [[nodiscard]] bool empty() const { return points_.empty(); }

 private:
  std::vector<Vec3> points_;
  std::vector<double> legs_, holds_, starts_;  // starts_[i]: start time of leg i
};

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/formation/trajectory.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"

/// A scenario's controllers, without the simulator: what `fnmpc run`, `fnmpc fly` (onboard)
/// and the ROS nodes build the same way.
namespace fnmpc::onboard {

/// CoM height of a vehicle resting on its feet [m] (the simulator's sim::World::kRestHeight,
/// checked where both are built).
inline constexpr double kGroundRestHeight = 0.1;

/// The leader's reference offsets: the waypoints (from the origin) or, in manual mode, the
/// random walk seeded from `seed`.
formation::WaypointTrajectory LeaderTrajectory(const config::ScenarioConfig& scenario,
                                               std::uint64_t seed);
/// The controller of vehicle `i` (throws std::invalid_argument on a bad index).
formation::ControllerConfig ControllerConfigFor(const config::ScenarioConfig& scenario, int i,
                                                const formation::WaypointTrajectory& trajectory);
/// Formation error of follower `i` from true positions (one per vehicle) and its true yaw:
/// the mean over its neighbours j of |(p_j - p_i) in its target frame - d_j| [m]; the
/// per-neighbour errors and relative positions go to `per_neighbour` / `relative` when given
/// (entries beyond the neighbour count stay NaN). NaN for the leader.
double FormationError(const config::ScenarioConfig& scenario, int i,
                      const std::vector<Vec3>& positions, double yaw,
                      std::array<double, formation::kMaxNeighbours>* per_neighbour = nullptr,
                      std::array<Vec3, formation::kMaxNeighbours>* relative = nullptr);

}  // namespace fnmpc::onboard

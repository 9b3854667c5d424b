// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/onboard/controller_setup.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/onboard/formation_print.hpp"

namespace fnmpc::onboard {

formation::WaypointTrajectory LeaderTrajectory(const config::ScenarioConfig& s,
                                               std::uint64_t seed) {
  if (s.leader_mode == "manual") {
    return formation::WaypointTrajectory::RandomWalk(s.walk_box, s.walk_moves, s.walk_min_leg,
                                                     s.walk_max_leg, s.walk_min_hold,
                                                     s.walk_max_hold, seed * 7919 + 17);
  }
  std::vector<Vec3> points{Vec3::Zero()};
  for (const Vec3& p : s.waypoints) points.push_back(p);
  return formation::WaypointTrajectory::Uniform(points, s.leg_duration, s.hold_duration);
}

formation::ControllerConfig ControllerConfigFor(const config::ScenarioConfig& sc, int i,
                                                const formation::WaypointTrajectory& trajectory) {
  if (i < 0 || i >= static_cast<int>(sc.vehicles.size())) {
    throw std::invalid_argument("[ControllerConfigFor] no vehicle " + std::to_string(i) +
                                " in scenario " + sc.name);
  }
  const auto& v = sc.vehicles[i];
  formation::ControllerConfig c;
  static_cast<formation::ControllerSettings&>(c) = sc;  // the settings every vehicle shares
  c.vehicle = i;
  c.leader = v.leader;
  c.leader_vehicle = sc.leader;  // followers: departure anchor, leader-down landing
  c.params = v.params;
  c.sensors = v.sensors;
  c.weights = v.leader ? sc.leader_weights : sc.follower_weights;
  c.pid.max_thrust = sc.thrust_max;
  // Each tie with its neighbour's graph depth, from the scenario's ties (controller.tie_weights).
  const std::vector<int> depth = TieDepths(sc);
  for (const auto& n : v.neighbours)
    c.neighbours.push_back({n.index, n.desired, depth.at(static_cast<std::size_t>(n.index))});
  // Collision avoidance: the other vehicles the relative sensor reports, in the tracking
  // slots that `controller.max_tracked` leaves after the formation neighbours.
  c.track_others = v.sensors.relative.enabled;
  c.frame = v.frame_control ? ocp::TargetFrame::kControl : ocp::TargetFrame::kInertial;
  c.relative_position_bound = v.relative_position_bound;
  c.trajectory = trajectory;
  if (std::isfinite(v.takeoff_height)) c.takeoff_height = v.takeoff_height;
  c.landing_time = config::LandingTime(sc, i);
  c.ground_height = kGroundRestHeight;
  return c;
}

double FormationError(const config::ScenarioConfig& sc, int i, const std::vector<Vec3>& positions,
                      double yaw, std::array<double, formation::kMaxNeighbours>* per_neighbour,
                      std::array<Vec3, formation::kMaxNeighbours>* relative) {
  const auto& v = sc.vehicles.at(static_cast<std::size_t>(i));
  if (per_neighbour) per_neighbour->fill(kNaN);
  if (relative) relative->fill(Vec3::Constant(kNaN));
  if (v.leader) return kNaN;
  double sum = 0.0;
  for (std::size_t j = 0; j < v.neighbours.size(); ++j) {
    Vec3 r = positions.at(static_cast<std::size_t>(v.neighbours[j].index)) -
             positions.at(static_cast<std::size_t>(i));
    if (v.frame_control) r = RotationZ(yaw).transpose() * r;
    const double e = (r - v.neighbours[j].desired).norm();
    if (per_neighbour) (*per_neighbour)[j] = e;
    if (relative) (*relative)[j] = r;
    sum += e;
  }
  return sum / static_cast<double>(v.neighbours.size());
}

}  // namespace fnmpc::onboard

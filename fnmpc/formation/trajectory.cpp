// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/trajectory.hpp"

#include <random>
#include <stdexcept>
#include <string>

namespace fnmpc::formation {

WaypointTrajectory::WaypointTrajectory(std::vector<Vec3> points, std::vector<double> leg_durations,
                                       std::vector<double> hold_durations)
    : points_(std::move(points)),
      legs_(std::move(leg_durations)),
      holds_(std::move(hold_durations)) {
  if (points_.empty()) throw std::invalid_argument("[WaypointTrajectory] no points");
  const std::size_t n = points_.size() - 1;
  if (legs_.size() != n || holds_.size() != n) {
    throw std::invalid_argument(
        "[WaypointTrajectory] need one leg and one hold duration per leg, got " +
        std::to_string(legs_.size()) + " and " + std::to_string(holds_.size()) + " for " +
        std::to_string(n) + " legs");
  }
  double t = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!(legs_[i] > 0.0) || !(holds_[i] >= 0.0)) {
      throw std::invalid_argument(
          "[WaypointTrajectory] leg durations must be > 0 and holds >= 0, leg " +
          std::to_string(i));
    }
    starts_.push_back(t);
    t += legs_[i] + holds_[i];
  }
}

WaypointTrajectory WaypointTrajectory::Uniform(std::vector<Vec3> points, double leg_duration,
                                               double hold_duration) {
  const std::size_t n = points.empty() ? 0 : points.size() - 1;
  return {std::move(points), std::vector<double>(n, leg_duration),
          std::vector<double>(n, hold_duration)};
}

WaypointTrajectory WaypointTrajectory::RandomWalk(const Vec3& size, int moves, double min_leg,
                                                  double max_leg, double min_hold, double max_hold,
                                                  std::uint64_t seed) {
  if (moves < 1 || !(min_leg > 0.0) || max_leg < min_leg || min_hold < 0.0 || max_hold < min_hold) {
    throw std::invalid_argument("[WaypointTrajectory] RandomWalk: bad moves or durations");
  }
  std::mt19937 rng(static_cast<std::mt19937::result_type>(seed));
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::uniform_real_distribution<double> leg(min_leg, max_leg), hold(min_hold, max_hold);
  std::vector<Vec3> points{Vec3::Zero()};
  std::vector<double> legs, holds;
  for (int i = 0; i < moves; ++i) {
    points.emplace_back(u(rng) * size.x(), u(rng) * size.y(), u(rng) * size.z());
    legs.push_back(leg(rng));
    holds.push_back(hold(rng));
  }
  return {std::move(points), std::move(legs), std::move(holds)};
}

void WaypointTrajectory::Sample(double t, Vec3* p, Vec3* v, Vec3* a) const {
  v->setZero();
  if (a != nullptr) a->setZero();
  if (points_.empty()) {
    p->setZero();
    return;
  }
  if (t <= 0.0 || legs_.empty()) {
    *p = points_.front();
    return;
  }
  for (std::size_t i = 0; i < legs_.size(); ++i) {
    const double tau = t - starts_[i];
    if (tau < 0.0) break;
    if (tau >= legs_[i] + holds_[i] && i + 1 < legs_.size()) continue;
    if (tau >= legs_[i]) {
      *p = points_[i + 1];
      return;
    }
    const double d = legs_[i];
    const double s = tau / d;
    const double s2 = s * s, s3 = s2 * s;
    const Vec3 delta = points_[i + 1] - points_[i];
    *p = points_[i] + delta * (10 * s3 - 15 * s3 * s + 6 * s3 * s2);
    *v = delta * (30 * s2 - 60 * s3 + 30 * s3 * s) / d;
    if (a != nullptr) *a = delta * (60 * s - 180 * s2 + 120 * s3) / (d * d);
    return;
  }
  *p = points_.back();
}

double WaypointTrajectory::TimeSinceStop(double t) const {
  if (t < 0.0 || legs_.empty()) return kInf;
  double since = kInf;
  for (std::size_t i = 0; i < legs_.size(); ++i) {
    const double tau = t - starts_[i];
    if (tau < 0.0) break;
    since = tau < legs_[i] ? 0.0 : tau - legs_[i];
  }
  return since;
}

double WaypointTrajectory::end_of_motion() const {
  return legs_.empty() ? 0.0 : starts_.back() + legs_.back();
}

double WaypointTrajectory::duration() const {
  return legs_.empty() ? 0.0 : starts_.back() + legs_.back() + holds_.back();
}

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/neighbour_plan.hpp"

#include <algorithm>
#include <cmath>

namespace fnmpc::formation {

bool PlanMessage::Valid() const {
  if (vehicle < 0 || points < 2 || points > kMaxPlanIntervals + 1) return false;
  if (!std::isfinite(stamp) || !(sample_time > 0.0) || !std::isfinite(sample_time)) return false;
  if (!disturbance.allFinite()) return false;
  for (int k = 0; k < points; ++k) {
    const auto i = static_cast<std::size_t>(k);
    if (!displacement[i].allFinite() || !velocity[i].allFinite() || !std::isfinite(thrust[i])) {
      return false;
    }
  }
  return true;
}

NeighbourPlans::NeighbourPlans(const std::vector<int>& vehicles)
    : vehicles_(vehicles), plans_(vehicles.size()) {}

bool NeighbourPlans::Receive(const PlanMessage& m) {
  if (!m.Valid()) return false;
  bool stored = false;
  for (std::size_t j = 0; j < vehicles_.size(); ++j) {
    if (vehicles_[j] != m.vehicle) continue;
    PlanMessage& p = plans_[j];
    if (std::isfinite(p.stamp) && !(m.stamp > p.stamp)) continue;  // older or a duplicate
    p = m;
    stored = true;
  }
  return stored;
}

bool NeighbourPlans::Fresh(int j, double t, double max_age) const {
  const PlanMessage& p = plans_.at(static_cast<std::size_t>(j));
  return std::isfinite(p.stamp) && std::isfinite(t) && t - p.stamp <= max_age;
}

namespace {

/// The plan at time s after its stamp: displacement, velocity, thrust.
void Sample(const PlanMessage& p, double s, Vec3* d, Vec3* v, double* thrust) {
  const int last = p.points - 1;
  const double x = s / p.sample_time;
  if (x >= last) {  // beyond the plan: constant velocity from its last point
    const auto l = static_cast<std::size_t>(last);
    *d = p.displacement[l] + (s - last * p.sample_time) * p.velocity[l];
    *v = p.velocity[l];
    *thrust = p.thrust[l];
    return;
  }
  const int i = std::clamp(static_cast<int>(std::floor(x)), 0, last - 1);
  const double f = x - i;
  const auto a = static_cast<std::size_t>(i), b = a + 1;
  *d = (1.0 - f) * p.displacement[a] + f * p.displacement[b];
  *v = (1.0 - f) * p.velocity[a] + f * p.velocity[b];
  *thrust = (1.0 - f) * p.thrust[a] + f * p.thrust[b];
}

}  // namespace

bool NeighbourPlans::Predict(int j, double t, double tau, double max_age, const Vec3& rel_now,
                             const Vec3& vel_now, PlanPrediction* out) const {
  if (!Fresh(j, t, max_age) || !rel_now.allFinite() || !vel_now.allFinite() ||
      !std::isfinite(tau)) {
    return false;
  }
  const PlanMessage& p = plans_[static_cast<std::size_t>(j)];
  const double age = std::max(0.0, t - p.stamp);
  Vec3 d_now, v_now, d, v;
  double thrust_now = kNaN, thrust = kNaN;
  Sample(p, age, &d_now, &v_now, &thrust_now);
  Sample(p, age + std::max(0.0, tau), &d, &v, &thrust);
  out->rel = rel_now + (d - d_now);
  out->vel = vel_now + (v - v_now);
  out->thrust = thrust;
  return true;
}

void NeighbourPlans::Clear() {
  for (PlanMessage& p : plans_) p.stamp = kNaN;
}

}  // namespace fnmpc::formation

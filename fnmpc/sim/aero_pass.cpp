// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/aero_pass.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "fnmpc/sim/downwash.hpp"
#include "fnmpc/sim/rotor_aero.hpp"

namespace fnmpc::sim::detail {

namespace {
// Cell side of the wake index [m]: about a wake's reach at the rotor plane (cutoff 3 x 0.3 m
// plus an arm); queries with a larger reach read more cells.
constexpr double kWakeCell = 1.5;
// Rounding margin of the reach tests [m] (the model's own tests are on the same quantities).
constexpr double kReachMargin = 1e-6;

// Horizontal distance [m] from p to the box [lo, hi] (x and y only).
double HorizontalDistanceToBox(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  const double dx = std::max({lo.x() - p.x(), 0.0, p.x() - hi.x()});
  const double dy = std::max({lo.y() - p.y(), 0.0, p.y() - hi.y()});
  return std::hypot(dx, dy);
}
}  // namespace

AeroPass::AeroPass(const WorldConfig& config, int n)
    : config_(config), n_(n), sources_(static_cast<std::size_t>(n)) {
  for (const VehicleSpec& v : config.vehicles) arm_.push_back(v.params.arm_length);
  for (int i = 0; i < n; ++i) {
    sources_[i].reserve(static_cast<std::size_t>(n));
    for (int j = 0; j < n; ++j) {
      if (j != i) sources_[i].push_back(j);
    }
  }
  if (!config.reality.wake) return;
  wakes_.reserve(static_cast<std::size_t>(n));
  fluctuation_.reserve(static_cast<std::size_t>(n) * n);
  for (int j = 0; j < n; ++j) {
    wakes_.emplace_back(config.downwash, config.reality.wake_turbulence);
    for (int i = 0; i < n; ++i) {
      fluctuation_.emplace_back(config.reality.wake_turbulence, config.seed, j, i);
    }
  }
}

bool AeroPass::active() const {
  return config_.wind.enabled || config_.downwash.enabled || config_.reality.rotor_aerodynamics;
}

void AeroPass::Prepare(const std::vector<Kinematics>& kin) {
  if (!config_.aero_culling || !config_.downwash.enabled) return;  // every pair (constructor)
  // The lowest point any vehicle evaluates a wake at (rotors within an arm of the CoM).
  double lowest_z = kInf, max_arm = 0.0;
  positions_.resize(static_cast<std::size_t>(n_));
  for (int i = 0; i < n_; ++i) {
    positions_[i] = kin[i].position;
    if (!positions_[i].allFinite()) {
      // No index this step: every pair.
      for (int k = 0; k < n_; ++k) {
        sources_[k].clear();
        for (int j = 0; j < n_; ++j) {
          if (j != k) sources_[k].push_back(j);
        }
      }
      return;
    }
    lowest_z = std::min(lowest_z, positions_[i].z() - arm_[i]);
    max_arm = std::max(max_arm, arm_[i]);
  }
  lowest_z -= kReachMargin;
  cells_.Build(positions_, kWakeCell);
  for (auto& list : sources_) list.clear();
  for (int j = 0; j < n_; ++j) {
    WakeSources src;
    if (wakes_.empty()) {
      src.Add(kin[j].position, kin[j].rotation.col(2));
    } else {
      src = wakes_[j].sources();
      if (!(src.hi.z() >= src.lo.z())) continue;  // no wake yet: nothing to evaluate
    }
    const double reach = WakeHorizontalReach(config_.downwash, src, lowest_z) + kReachMargin;
    if (!std::isfinite(reach)) {
      for (int i = 0; i < n_; ++i) {
        if (i != j) sources_[i].push_back(j);
      }
      continue;
    }
    const double top = WakeTop(config_.downwash, src) + kReachMargin;
    const Vec3 centre = 0.5 * (src.lo + src.hi);
    const double half_diagonal = 0.5 * std::hypot(src.hi.x() - src.lo.x(), src.hi.y() - src.lo.y());
    cells_.Near(centre, half_diagonal + reach + max_arm + kReachMargin, &near_);
    for (const int i : near_) {
      if (i == j || positions_[i].z() - arm_[i] > top) continue;  // wholly above the wake
      if (HorizontalDistanceToBox(positions_[i], src.lo, src.hi) <= reach + arm_[i]) {
        sources_[i].push_back(j);
      }
    }
  }
}

void AeroPass::Record(int i, double t, const Vec3& position, const Vec3& thrust_axis,
                      double thrust) {
  wakes_[i].Record(t, position, thrust_axis, thrust);
}

void AeroPass::StepFluctuations(int observer, double t, const std::vector<Kinematics>& kin) {
  if (wakes_.empty() || !config_.downwash.enabled) return;
  // Fluctuations advance with the scales at the observer's centre of mass (a dropped wake
  // has none there: Step would leave its fluctuation unchanged).
  for (const int j : sources_[observer]) {
    double uc = 0.0, hw = 0.0;
    wakes_[j].MeanVelocity(t, kin[observer].position, &uc, &hw);
    fluctuation_[j * n_ + observer].Step(config_.physics_dt, uc, hw);
  }
}

Vec3 AeroPass::WakeAir(int i, double t, const Vec3& point, const std::vector<Kinematics>& kin,
                       const std::vector<double>& total_thrust) const {
  const DownwashSettings& dw = config_.downwash;
  Vec3 air = Vec3::Zero();
  for (const int j : sources_[i]) {
    if (wakes_.empty()) {
      air += DownwashVelocity(dw, kin[j].position, kin[j].rotation.col(2), total_thrust[j], point);
      continue;
    }
    double uc = 0.0, hw = 0.0, r = 0.0;
    Vec3 axis;
    air += wakes_[j].MeanVelocity(t, point, &uc, &hw, &axis, &r);
    air += fluctuation_[j * n_ + i].Velocity(axis, uc, hw, r);
  }
  return air;
}

void AeroPass::VehicleWrench(int i, double t, const Vec3& wind_air,
                             const std::vector<Kinematics>& kin,
                             const std::vector<double>& total_thrust, Vehicle& v) const {
  const AeroRealitySettings& re = config_.reality;
  const DownwashSettings& dw = config_.downwash;
  // The ideal plant adds the wind and then each steady jet in turn; the reality models add
  // the wakes' sum to the wind. Both orders are kept: each plant stays bit-identical to its
  // pinned results (tests/sim/reality_off_test.cpp and the recorded runs).
  const bool reality = re.rotor_aerodynamics || re.wake;
  const Vec3 c_rotor = 0.25 * config_.drag_coefficient;  // drag split over the 4 rotor points
  const Mat3& rot = kin[i].rotation;
  const Vec3& pos = kin[i].position;
  const Vec3& vel = kin[i].velocity;
  const Vec3 axis = rot.col(2);
  v.aero_force.setZero();
  v.aero_torque.setZero();
  for (int r = 0; r < 4; ++r) {
    const Vec3 arm_w = rot * v.rotor_b[r];
    const Vec3 point = pos + arm_w;
    Vec3 air;
    if (reality) {
      air = wind_air;
      if (dw.enabled) air += WakeAir(i, t, point, kin, total_thrust);
    } else {
      air = Vec3::Zero();
      if (config_.wind.enabled) air += wind_air;
      if (dw.enabled) {
        for (int j = 0; j < n_; ++j) {
          if (j == i) continue;
          air +=
              DownwashVelocity(dw, kin[j].position, kin[j].rotation.col(2), total_thrust[j], point);
        }
      }
    }
    const Vec3 rel = air - vel;
    Vec3 f = QuadraticDrag(rot, c_rotor, rel);
    if (re.rotor_aerodynamics && !v.status.motors_killed) {
      const double still = v.params.thrust_constant * v.rpm[r] * v.rpm[r];
      const double omega = v.rpm[r] * kRpmToRadPerSec;
      double ratio = AxialInflowThrustRatio(re.blade, still, omega, -rel.dot(axis));
      if (config_.ground) ratio *= GroundEffectRatio(re.blade.radius, point.z());
      f += (ratio - 1.0) * still * axis;
      f += RotorDrag(re.rotor_drag, v.params.mass, v.rpm[r] / v.hover_rpm, axis, rel);
    }
    v.aero_force += f;
    v.aero_torque += arm_w.cross(f);
  }
}

}  // namespace fnmpc::sim::detail

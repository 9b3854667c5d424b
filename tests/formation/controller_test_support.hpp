// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Shared by the formation tests: the reference vehicle, controller configs, and the NMPC's
// own model as a plant on a flat ground.
#include <vector>

#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/model/quadrotor_model.hpp"
#include "fnmpc/model/rk4.hpp"

namespace fnmpc::formation::testing {

constexpr double kTs = 0.05;
constexpr double kGround = 0.1;

inline model::VehicleParams Vehicle() {
  model::VehicleParams p;
  p.throttle.c(0, 0) = 1.295532269;
  p.throttle.c(0, 1) = -0.1703711916;
  p.throttle.c(0, 2) = 0.008857434141;
  p.throttle.c(0, 3) = -0.0001635235747;
  p.throttle.c(1, 0) = 0.2929197223;
  p.throttle.c(1, 1) = -0.01461840844;
  p.throttle.c(1, 2) = 0.0002619815754;
  p.throttle.c(2, 0) = -0.01292856667;
  p.throttle.c(2, 1) = 0.0002213855606;
  p.throttle.c(3, 0) = 0.0003812494858;
  return p;
}

inline ControllerConfig BaseConfig(bool leader) {
  ControllerConfig c;
  c.vehicle = leader ? 0 : 1;
  c.leader = leader;
  c.params = Vehicle();
  c.takeoff_time = 0.5;
  c.hover_before_switch = 1.0;
  c.ground_height = kGround;
  c.voltage_filter_time = 0.0;
  c.trajectory = WaypointTrajectory::Uniform({Vec3::Zero(), Vec3(0.5, 0, 0)}, 3.0, 2.0);
  c.trajectory_start = 100.0;  // the leader holds its hover point in these tests
  if (!leader) c.neighbours = {{0, Vec3(1.0, -1.0, 0.0)}};
  return c;
}

/// The NMPC model as plant (RK4 over one sampling time, 10 sub-steps) on a flat ground.
struct Plant {
  Vec<9> x = Vec<9>::Zero();
  /// Vertical speed at the last ground contact [m/s] (NaN: none yet).
  double impact_vz = kNaN;
  Plant() { x[2] = kGround; }
  void Step(const ControlOutput& u) {
    const Vec3 in(u.thrust, u.roll, u.pitch);
    for (int i = 0; i < 10; ++i) {
      const bool airborne = x[2] > kGround;
      x = model::Rk4<model::QuadrotorModel>(x, in, u.yaw, model::AttitudeModelParams{}, kTs / 10,
                                            1);
      if (x[2] < kGround) {
        if (airborne) impact_vz = x[5];
        x[2] = kGround;
        x.segment<3>(3).setZero();
      }
    }
  }
  /// An exact motion-capture sample of the plant for `vehicle`, stamped and arriving at t.
  [[nodiscard]] Measurement Mocap(int vehicle, double t) const {
    Measurement m;
    m.kind = SensorKind::kMocapPose;
    m.vehicle = vehicle;
    m.stamp = m.arrival = t;
    m.position = x.head<3>();
    m.euler = x.tail<3>();
    return m;
  }
  [[nodiscard]] estimation::VehicleEstimate Estimate(double t) const {
    estimation::VehicleEstimate e;
    e.valid = true;
    e.time = t;
    e.mode = estimation::VehicleMode::kFlying;
    e.position = x.head<3>();
    e.velocity = x.segment<3>(3);
    e.euler = x.tail<3>();
    return e;
  }
};

/// Flies the leader from the ground until `until` [s]; returns every output.
inline std::vector<ControlOutput> Fly(VehicleController* c, Plant* plant, double until) {
  std::vector<ControlOutput> out;
  for (int k = 0; k * kTs <= until; ++k) {
    out.push_back(c->ControlWithEstimates(k * kTs, plant->Estimate(k * kTs), {}));
    plant->Step(out.back());
  }
  return out;
}

}  // namespace fnmpc::formation::testing

// SPDX-License-Identifier: BSD-3-Clause
#pragma once
// The validation scene shared by tools/reality_validation.cpp (plots, docs/simulator.md) and
// tests/sim/reality_validation_test.cpp: two copies of a vehicle hovering, held in place, the
// lower one dz below the upper, far from the ground.

#include <vector>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/model/vehicle_params.hpp"
#include "fnmpc/sim/world.hpp"

namespace fnmpc::validation {

/// The lower vehicle's aerodynamic force [N, world] at every `every`-th physics step from
/// `warmup` (the wake's build-up) to `steps`; `reality` switches the advected turbulent wake and
/// the rotor aerodynamics (otherwise the ideal plant's steady jet acting as body drag).
inline std::vector<Vec3> ForceBelowHoveringVehicle(const model::VehicleParams& p, double dz,
                                                   bool reality, int steps, int warmup, int every) {
  sim::WorldConfig c;
  for (int i = 0; i < 2; ++i) {
    sim::VehicleSpec v;
    v.params = p;
    for (SensorSpec* s : {&v.sensors.mocap, &v.sensors.imu, &v.sensors.optical_flow,
                          &v.sensors.compass, &v.sensors.battery, &v.sensors.relative}) {
      s->enabled = false;
    }
    v.initial_throttle = p.throttle.Throttle(p.mass * kGravity / 4.0, 16.8);
    c.vehicles.push_back(v);
  }
  c.ground = false;
  c.battery.fixed_voltage = true;
  c.downwash.enabled = true;
  c.reality.wake = reality;
  c.reality.rotor_aerodynamics = reality;
  const Vec3 upper(0.0, 0.0, 20.0), lower(0.0, 0.0, 20.0 - dz);
  c.vehicles[0].position = upper;
  c.vehicles[1].position = lower;
  sim::World w(c);
  std::vector<Vec3> f;
  for (int k = 0; k < steps; ++k) {
    w.SetPose(0, upper, Vec3::Zero());
    w.SetPose(1, lower, Vec3::Zero());
    w.StepOnce();
    if (k >= warmup && (k - warmup) % every == 0) f.push_back(w.GetTrueState(1).aero_force);
  }
  return f;
}

}  // namespace fnmpc::validation

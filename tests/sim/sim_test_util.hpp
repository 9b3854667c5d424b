// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/sim/world.hpp"

namespace fnmpc::sim::test {

/// The shipped default vehicle.
inline model::VehicleParams ShippedVehicle() {
  return config::LoadVehicleFile(std::string(FNMPC_SOURCE_DIR) +
                                 "/config/vehicles/storm-drone-4.yaml");
}

/// A world config with `n` default vehicles 2 m apart on the ground, all sensors off.
inline WorldConfig QuietConfig(int n) {
  WorldConfig c;
  const model::VehicleParams p = ShippedVehicle();
  for (int i = 0; i < n; ++i) {
    VehicleSpec v;
    v.params = p;
    v.position = Vec3(2.0 * i, 0.0, World::kRestHeight);
    for (SensorSpec* s : {&v.sensors.mocap, &v.sensors.imu, &v.sensors.optical_flow,
                          &v.sensors.compass, &v.sensors.battery, &v.sensors.relative}) {
      s->enabled = false;
    }
    c.vehicles.push_back(v);
  }
  return c;
}

}  // namespace fnmpc::sim::test

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <vector>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/sim/cell_list.hpp"
#include "fnmpc/sim/world_settings.hpp"
#include "fnmpc/sim/world_vehicle.hpp"

/// The sensors of sim::World (docs/simulator.md "Sensors" and "Reality"): each vehicle's
/// samples on their schedules from the kinematics at the start of a step, with the sensor
/// reality models. A vehicle's draws come from its own streams only, so vehicles can be
/// sampled in any order (or in parallel) with the same results.
namespace fnmpc::sim::detail {

/// The relative sensor's candidate lookup for one step: a cell list of the step's positions
/// with cells of side `side` [m], or none (cells == nullptr: every vehicle is tested).
struct RelativeIndex {
  const CellList* cells = nullptr;
  double side = 0.0;
};

/// Once per autopilot tick: bias random walks, and the autopilot's own attitude estimate
/// (gyro with bias and noise integrated, corrected toward a noisy external attitude).
void UpdateSensorReality(const WorldConfig& config, const Kinematics& kin, Vehicle& v);

/// The samples of vehicle `vi` (state v) due at time t [s] into *out (cleared first), in
/// generation order; `kin` holds every vehicle's kinematics.
void SampleSensors(const WorldConfig& config, int vi, double t, const std::vector<Kinematics>& kin,
                   const RelativeIndex& index, Vehicle& v, std::vector<Measurement>* out);

/// Whether vehicle state v has a relative sample due at time t [s] (to build the index only
/// on those steps).
bool RelativeSampleDue(const Vehicle& v, double t);

}  // namespace fnmpc::sim::detail

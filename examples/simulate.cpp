// SPDX-License-Identifier: BSD-3-Clause
// The simulator's loop, as a program that tests a controller would write it: a sim::World
// (MuJoCo) with a leader and a follower, each flown by its own formation::VehicleController.
// Every 50 ms the world's delivered measurements go to the vehicle that carries the sensor
// (Process), each controller gives a command (Control) and the world's emulated autopilots
// take it (SetCommand); then the world steps. The leader takes off and flies a 1 m leg; the
// follower keeps 1 m behind and 1 m to its side from its relative sensor.
#include <algorithm>
#include <cstdio>
#include <vector>

#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/sim/world.hpp"

using namespace fnmpc;

namespace {

// The reference vehicle, config/vehicles/storm-drone-4.yaml (a program with the
// configuration layer reads it with config::LoadVehicleFile; the installed package has no YAML).
model::VehicleParams StormDrone4() {
  model::VehicleParams p;  // mass, inertia, rotor constants and attitude model: the file's
  const double c[4][4] = {{1.295532269, -0.1703711916, 0.008857434141, -0.0001635235747},
                          {0.2929197223, -0.01461840844, 0.0002619815754, 0},
                          {-0.01292856667, 0.0002213855606, 0, 0},
                          {0.0003812494858, 0, 0, 0}};
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; i + j < 4; ++j) p.throttle.c(i, j) = c[i][j];
  }
  p.attitude_kp = Vec3(400.0, 400.0, 600.0);
  p.attitude_kd = Vec3(48.12, 52.12, 39.06);
  return p;
}

}  // namespace

int main() {
  const Vec3 offset(-1.0, -1.0, 0.0);  // follower position minus leader position [m]

  sim::WorldConfig world_config;  // 1 ms physics, emulated autopilots at 250 Hz, ground
  world_config.vehicles.resize(2);
  for (sim::VehicleSpec& v : world_config.vehicles) v.params = StormDrone4();
  world_config.vehicles[0].position = Vec3(0, 0, sim::kRestHeight);
  world_config.vehicles[1].position = Vec3(offset.x(), offset.y(), sim::kRestHeight);
  sim::World world(world_config);  // throws on a bad configuration

  std::vector<formation::VehicleController> controllers;
  for (int v = 0; v < 2; ++v) {
    formation::ControllerConfig c;  // the defaults of the scenario files' controller block
    c.vehicle = v;
    c.leader = v == 0;
    c.leader_vehicle = 0;
    c.params = world_config.vehicles[v].params;    // the controller's vehicle file
    c.sensors = world_config.vehicles[v].sensors;  // and its sensors' noise
    c.ground_height = sim::kRestHeight;
    c.trajectory_start = 8.0;  // [s]
    c.trajectory = formation::WaypointTrajectory::Uniform({Vec3::Zero(), Vec3(1, 0, 0)}, 4.0, 2.0);
    if (v == 1) c.neighbours = {{0, -offset}};  // d = p_leader - p_follower
    controllers.emplace_back(c);
  }

  const double ts = controllers[0].config().rti.sample_time;  // control period [s]
  const double end = 18.0;                                    // [s]
  double max_formation_error = 0.0;  // |p_leader - p_follower + offset| in the NMPC phase [m]
  Measurement m;
  while (world.time() < end) {
    // Measurements in: each to the controller of the vehicle that carries the sensor.
    while (world.PopMeasurement(&m)) controllers.at(m.vehicle).Process(m);
    // Commands out, to the emulated autopilots.
    for (int v = 0; v < 2; ++v) {
      const formation::ControlOutput out = controllers[v].Control(world.time());
      world.SetCommand(v, {out.thrust, out.roll, out.pitch, out.yaw, out.throttle});
    }
    const sim::TrueState leader = world.GetTrueState(0), follower = world.GetTrueState(1);
    if (controllers[1].phase() == formation::FlightPhase::kNmpc &&
        world.time() > controllers[1].nmpc_start() + 3.0) {
      max_formation_error =
          std::max(max_formation_error, (follower.position - leader.position - offset).norm());
    }
    world.Step(ts);
  }
  const sim::TrueState leader = world.GetTrueState(0), follower = world.GetTrueState(1);
  std::printf("t = %.1f s: leader at (%.2f, %.2f, %.2f), follower at (%.2f, %.2f, %.2f)\n",
              world.time(), leader.position.x(), leader.position.y(), leader.position.z(),
              follower.position.x(), follower.position.y(), follower.position.z());
  const Vec3 leader_goal = controllers[0].anchor() + Vec3(1, 0, 0);
  const double leader_error = (leader.position - leader_goal).norm();
  std::printf("leader %.3f m from the end of its leg; largest formation error %.3f m\n",
              leader_error, max_formation_error);
  const bool ok = controllers[0].phase() == formation::FlightPhase::kNmpc &&
                  controllers[1].phase() == formation::FlightPhase::kNmpc && leader_error < 0.1 &&
                  max_formation_error < 0.3;
  std::printf("%s\n", ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}

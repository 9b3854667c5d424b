// SPDX-License-Identifier: BSD-3-Clause
// The light-weight attitude loop of fnmpc/sysid against the MuJoCo World it stands for.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/sim/world.hpp"
#include "fnmpc/sysid/attitude_fit.hpp"

namespace fnmpc::sysid {
namespace {

class AttitudeLoopSimTest : public ::testing::TestWithParam<int> {};

TEST_P(AttitudeLoopSimTest, LightModelFollowsTheWorld) {
  const int axis = GetParam();
  // Given the shipped vehicle hovering in the World and a step of one reference,
  model::VehicleParams p = config::LoadVehicleFile(std::string(FNMPC_SOURCE_DIR) +
                                                   "/config/vehicles/storm-drone-4.yaml");
  sim::WorldConfig c;
  sim::VehicleSpec v;
  v.params = p;
  v.position = Vec3(0.0, 0.0, 50.0);
  for (SensorSpec* s : {&v.sensors.mocap, &v.sensors.imu, &v.sensors.optical_flow,
                        &v.sensors.compass, &v.sensors.battery, &v.sensors.relative}) {
    s->enabled = false;
  }
  v.initial_throttle = p.throttle.Throttle(p.mass * kGravity / 4.0, 16.8);
  c.vehicles = {v};
  c.ground = false;
  c.visual_geometry = false;
  c.battery.fixed_voltage = true;
  sim::World world(c);
  const double weight = p.mass * kGravity;
  world.SetCommand(0, {weight, 0.0, 0.0, 0.0});
  world.Step(0.5);
  const double step = axis == 2 ? 0.02 : 0.1;
  std::vector<double> t, ref, y_world;
  const double t0 = world.time();
  for (int k = 0; k < 500; ++k) {  // 0.2 s at zero, then 1.8 s of step, 250 Hz
    const double r = k < 50 ? 0.0 : step;
    sim::AttitudeCommand cmd{weight, 0.0, 0.0, 0.0};
    (axis == 0 ? cmd.roll : axis == 1 ? cmd.pitch : cmd.yaw) = r;
    if (axis < 2) cmd.thrust = weight / std::cos(r);
    world.SetCommand(0, cmd);
    t.push_back(world.time() - t0);
    ref.push_back(r);
    y_world.push_back(world.GetTrueState(0).euler[axis]);
    world.Step(0.004);
  }
  // When the light-weight model is driven by the same reference,
  AttitudeLoopSettings st;
  st.motor_time_constant = c.motor_time_constant;
  st.autopilot_rate_hz = c.autopilot_rate_hz;
  st.physics_dt = c.physics_dt;
  std::vector<double> y_light;
  SimulateAttitudeLoop<double>(t, ref, p.attitude_gain[axis], p.attitude_kp[axis],
                               p.attitude_kd[axis], y_world[0], st, &y_light);
  // Then both responses agree within 0.2 % of the step (RMS) and 1 % (max).
  double ss = 0.0, worst = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double e = std::abs(y_light[i] - y_world[i]);
    ss += e * e;
    worst = std::max(worst, e);
  }
  const double rms = std::sqrt(ss / static_cast<double>(t.size()));
  std::printf("axis %d: light vs World rms %.2e rad, max %.2e rad (step %.2f rad)\n", axis, rms,
              worst, step);
  EXPECT_LT(rms, 0.002 * step);
  EXPECT_LT(worst, 0.01 * step);
}

INSTANTIATE_TEST_SUITE_P(RollPitchYaw, AttitudeLoopSimTest, ::testing::Values(0, 1, 2));

}  // namespace
}  // namespace fnmpc::sysid

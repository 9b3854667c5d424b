// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "fnmpc/sim/world.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

struct FirstOrderFit {
  double tau = 0.0;   ///< [s]
  double gain = 0.0;  ///< [-]
};

/// Least-squares fit of y(t) = y0 + gain * step * (1 - exp(-t / tau)) over a tau grid,
/// with the gain in closed form for each tau.
FirstOrderFit FitStep(const std::vector<double>& t, const std::vector<double>& y, double y0,
                      double step) {
  FirstOrderFit best;
  double best_err = kInf;
  for (double tau = 0.01; tau < 0.5; tau += 0.0002) {
    double bb = 0.0, by = 0.0;
    for (std::size_t i = 0; i < t.size(); ++i) {
      const double b = step * (1.0 - std::exp(-t[i] / tau));
      bb += b * b;
      by += b * (y[i] - y0);
    }
    const double gain = by / bb;
    double err = 0.0;
    for (std::size_t i = 0; i < t.size(); ++i) {
      const double r = y[i] - y0 - gain * step * (1.0 - std::exp(-t[i] / tau));
      err += r * r;
    }
    if (err < best_err) {
      best_err = err;
      best = {tau, gain};
    }
  }
  return best;
}

class AttitudeStepTest : public ::testing::TestWithParam<int> {};

TEST_P(AttitudeStepTest, ClosedLoopMatchesFirstOrderModel) {
  const int axis = GetParam();
  // Given a vehicle hovering high up under the autopilot,
  WorldConfig c = test::QuietConfig(1);
  c.ground = false;
  c.battery.fixed_voltage = true;
  const model::VehicleParams& p = c.vehicles[0].params;
  c.vehicles[0].position = Vec3(0.0, 0.0, 100.0);
  World world(c);
  const double weight = p.mass * kGravity;
  world.SetCommand(0, AttitudeCommand{weight, 0.0, 0.0, 0.0});
  world.Step(1.0);
  // When the reference of one axis steps by a small angle,
  const double step = axis == 2 ? 0.05 : 0.1;
  AttitudeCommand cmd{weight, 0.0, 0.0, 0.0};
  (axis == 0 ? cmd.roll : axis == 1 ? cmd.pitch : cmd.yaw) = step;
  if (axis < 2) cmd.thrust = weight / std::cos(step);
  const double y0 = world.GetTrueState(0).euler[axis];
  const double t0 = world.time();
  world.SetCommand(0, cmd);
  std::vector<double> t, y;
  for (int k = 0; k < 1000; ++k) {
    world.StepOnce();
    t.push_back(world.time() - t0);
    y.push_back(world.GetTrueState(0).euler[axis]);
  }
  // Then the fitted first-order time constant and gain agree with the vehicle file
  // within 15 %.
  const FirstOrderFit fit = FitStep(t, y, y0, step);
  const double tau = p.attitude_time_constant[axis];
  const double gain = p.attitude_gain[axis];
  RecordProperty("fitted_tau", std::to_string(fit.tau));
  RecordProperty("fitted_gain", std::to_string(fit.gain));
  std::printf("axis %d: fitted tau %.4f s (file %.4f), gain %.3f (file %.3f)\n", axis, fit.tau, tau,
              fit.gain, gain);
  EXPECT_NEAR(fit.tau, tau, 0.15 * tau);
  EXPECT_NEAR(fit.gain, gain, 0.15 * gain);
}

INSTANTIATE_TEST_SUITE_P(RollPitchYaw, AttitudeStepTest, ::testing::Values(0, 1, 2));

}  // namespace
}  // namespace fnmpc::sim

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/calibration.hpp"

#include <gtest/gtest.h>

#include <random>
#include <stdexcept>

namespace fnmpc::sysid {
namespace {

// A 12 s flight of the prediction model itself (true bias) under a hover PD with doublets,
// logged at 50 Hz with mocap-like noise.
FlightLog ModelFlight(const model::VehicleParams& truth, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  const auto m = model::AttitudeModelParams::From(truth);
  FlightLog log;
  Vec<9> x = Vec<9>::Zero();
  const double dt = 0.02;
  for (int k = 0; k < 600; ++k) {
    const double t = k * dt;
    Vec<9> z = x;
    for (int i = 0; i < 3; ++i) {
      z[i] += 0.001 * n(rng);
      z[3 + i] += 0.01 * n(rng);
      z[6 + i] += 0.002 * n(rng);
    }
    const Vec3 acc = -2.0 * z.head<3>() - 2.5 * z.segment<3>(3);
    const double phase = std::fmod(t, 2.0);
    Vec<4> u(truth.mass * (kGravity + acc.z()) * (phase < 0.3 ? 1.08 : 1.0),
             -acc.y() / kGravity + (phase >= 0.6 && phase < 0.9 ? 0.05 : 0.0),
             acc.x() / kGravity + (phase >= 1.2 && phase < 1.5 ? -0.05 : 0.0), 0.0);
    log.t.push_back(t);
    log.state.push_back(z);
    log.command.push_back(u);
    log.voltage.push_back(16.0);
    x = PredictStep<double>(x, u, truth.bias.roll, truth.bias.pitch, truth.bias.thrust_scale, m, dt,
                            4);
  }
  return log;
}

TEST(CalibrationTest, RecoversBiasesOfTheModelItself) {
  // Given a flight of the prediction model with injected biases,
  model::VehicleParams truth;
  truth.bias = {0.015, -0.02, 1.04};
  const FlightLog log = ModelFlight(truth, 9);
  // When a vehicle without bias is calibrated on it,
  const CalibrationResult r = Calibrate(model::VehicleParams{}, log);
  // Then the biases are recovered and the prediction error drops.
  ASSERT_TRUE(r.converged);
  EXPECT_NEAR(r.bias.roll, 0.015, 0.001);
  EXPECT_NEAR(r.bias.pitch, -0.02, 0.001);
  EXPECT_NEAR(r.bias.thrust_scale, 1.04, 0.003);
  EXPECT_LT(r.position_error_after, 0.5 * r.position_error_before);
  EXPECT_GT(r.windows, 15);
}

TEST(CalibrationTest, RejectsBadLogs) {
  // Given logs that are too short, inconsistent or not increasing in time,
  model::VehicleParams p;
  FlightLog log = ModelFlight(p, 1);
  FlightLog shortlog = log;
  shortlog.t.resize(10);
  shortlog.state.resize(10);
  shortlog.command.resize(10);
  FlightLog mismatched = log;
  mismatched.command.pop_back();
  FlightLog backwards = log;
  backwards.t[5] = backwards.t[4];
  // When / Then calibration refuses them.
  EXPECT_THROW(Calibrate(p, shortlog), std::invalid_argument);
  EXPECT_THROW(Calibrate(p, mismatched), std::invalid_argument);
  EXPECT_THROW(Calibrate(p, backwards), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::sysid

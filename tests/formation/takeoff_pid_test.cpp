// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/takeoff_pid.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "tests/formation/controller_test_support.hpp"

namespace fnmpc::formation {
namespace {

using testing::kGround;
using testing::kTs;
using testing::Plant;

constexpr double kDeg = std::numbers::pi / 180.0;

struct TakeoffResult {
  double max_drift = 0.0;    // largest horizontal distance from the start [m]
  double final_drift = 0.0;  // at the end [m]
  double max_tilt_ref = 0.0;
  double final_height = kNaN;
};

// Climbs from the ground to 1 m at 0.5 m/s with the PID and hovers until `until` [s], on the
// NMPC model as plant whose autopilot levels to a constant attitude bias (roll, pitch) [rad]:
// the commanded attitude plus the bias is what the vehicle flies. `hold`: the horizontal
// position error is given (else velocity damping only).
TakeoffResult FlyTakeoff(double bias_roll, double bias_pitch, bool hold, double until) {
  TakeoffPid pid(TakeoffPidConfig{}, 1.37);
  pid.Reset(1.37 * kGravity);
  Plant plant;
  const Vec<2> start = plant.x.head<2>();
  double z_ref = plant.x[2];
  TakeoffResult r;
  for (int k = 0; k * kTs <= until; ++k) {
    double vz_ref = 0.0;
    if (z_ref < 1.0) {
      z_ref = std::min(1.0, z_ref + 0.5 * kTs);
      vz_ref = z_ref < 1.0 ? 0.5 : 0.0;
    }
    const Vec<2> error = hold ? Vec<2>(start - plant.x.head<2>()) : Vec<2>::Constant(kNaN);
    const PidCommand c =
        pid.Update(kTs, z_ref, vz_ref, plant.x[2], plant.x.segment<3>(3), plant.x.tail<3>(), error);
    r.max_tilt_ref = std::max({r.max_tilt_ref, std::abs(c.roll), std::abs(c.pitch)});
    ControlOutput u;
    u.thrust = c.thrust;
    u.roll = c.roll + bias_roll;
    u.pitch = c.pitch + bias_pitch;
    u.yaw = 0.0;
    plant.Step(u);
    r.max_drift = std::max(r.max_drift, (plant.x.head<2>() - start).norm());
  }
  r.final_drift = (plant.x.head<2>() - start).norm();
  r.final_height = plant.x[2];
  return r;
}

TEST(TakeoffPidTest, HorizontalPositionHoldBoundsTheDriftOfAnAttitudeBias) {
  // Given a vehicle whose level calibration is off by 2 deg in roll and -1.5 deg in pitch
  // (the upper end of docs/simulator.md's drawn biases)
  // When it takes off by PID and hovers for 8 s with the horizontal position hold
  const TakeoffResult held = FlyTakeoff(2.0 * kDeg, -1.5 * kDeg, true, 8.0);
  // Then it reaches its height, its horizontal drift stays below the steady offset the PD part
  // alone would leave, g b / kp_xy (0.19 m for the combined 2.5 deg), and the integral has
  // removed most of it by the end
  const double b = std::hypot(2.0, 1.5) * kDeg;
  const double pd_offset = kGravity * b / TakeoffPidConfig{}.kp_xy;
  EXPECT_NEAR(held.final_height, 1.0, 0.03);
  EXPECT_LT(held.max_drift, pd_offset);
  EXPECT_LT(held.final_drift, 0.05);
  // with roll/pitch references inside the tilt bound, small
  EXPECT_LE(held.max_tilt_ref, TakeoffPidConfig{}.max_tilt);
  EXPECT_LT(held.max_tilt_ref, 0.1);
  // while velocity damping alone (the former take-off controller) drifts much further
  const TakeoffResult damped = FlyTakeoff(2.0 * kDeg, -1.5 * kDeg, false, 8.0);
  EXPECT_GT(damped.max_drift, 3.0 * held.max_drift);
}

TEST(TakeoffPidTest, HorizontalIntegralLearnsTheBiasWithinItsBound) {
  // Given the hold on a biased plant flown long enough to settle
  TakeoffPid pid(TakeoffPidConfig{}, 1.37);
  pid.Reset(1.37 * kGravity);
  Plant plant;
  plant.x[2] = 1.0;
  const double bias = 1.0 * kDeg;
  for (int k = 0; k * kTs <= 30.0; ++k) {
    const PidCommand c = pid.Update(kTs, 1.0, 0.0, plant.x[2], plant.x.segment<3>(3),
                                    plant.x.tail<3>(), Vec<2>(-plant.x.head<2>()));
    ControlOutput u;
    u.thrust = c.thrust;
    u.roll = c.roll;
    u.pitch = c.pitch + bias;  // pitch up: accelerates along +x at yaw 0
    u.yaw = 0.0;
    plant.Step(u);
  }
  // Then the vehicle is back at its hold point and the x integral cancels the bias: the pitch
  // reference settles at -b, i.e. an integral acceleration of -g b (pitch = a_x / g)
  EXPECT_LT(plant.x.head<2>().norm(), 0.01);
  EXPECT_NEAR(pid.HorizontalIntegral().x(), -kGravity * bias, 0.01);
  EXPECT_NEAR(pid.HorizontalIntegral().y(), 0.0, 0.01);
  // and Reset clears it
  pid.Reset(1.37 * kGravity);
  EXPECT_EQ(pid.HorizontalIntegral().norm(), 0.0);
}

TEST(TakeoffPidTest, IntegralIsBoundedAndNaNPositionMeansDampingOnly) {
  TakeoffPid pid(TakeoffPidConfig{}, 1.37);
  pid.Reset(1.37 * kGravity);
  // A large persistent error winds the integral only to its bound
  for (int k = 0; k < 1000; ++k) {
    pid.Update(kTs, 1.0, 0.0, 1.0, Vec3::Zero(), Vec3::Zero(), Vec<2>(5.0, -5.0));
  }
  EXPECT_DOUBLE_EQ(pid.HorizontalIntegral().x(), TakeoffPidConfig{}.max_integral_xy);
  EXPECT_DOUBLE_EQ(pid.HorizontalIntegral().y(), -TakeoffPidConfig{}.max_integral_xy);
  // and the references stay within the tilt bound
  const PidCommand big =
      pid.Update(kTs, 1.0, 0.0, 1.0, Vec3::Zero(), Vec3::Zero(), Vec<2>(5.0, -5.0));
  EXPECT_DOUBLE_EQ(std::abs(big.pitch), TakeoffPidConfig{}.max_tilt);
  EXPECT_DOUBLE_EQ(std::abs(big.roll), TakeoffPidConfig{}.max_tilt);
  // A non-finite position error: only the velocity damping acts, the integral is held
  pid.Reset(1.37 * kGravity);
  const PidCommand damped =
      pid.Update(kTs, 1.0, 0.0, 1.0, Vec3(0.1, 0.0, 0.0), Vec3::Zero(), Vec<2>::Constant(kNaN));
  EXPECT_NEAR(damped.pitch, -TakeoffPidConfig{}.kv_xy * 0.1 / kGravity, 1e-12);
  EXPECT_NEAR(damped.roll, 0.0, 1e-12);
  EXPECT_EQ(pid.HorizontalIntegral().norm(), 0.0);
  // Invalid gains are named
  TakeoffPidConfig bad;
  bad.kp_xy = -1.0;
  try {
    TakeoffPid p(bad, 1.37);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("kp_xy"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fnmpc::formation

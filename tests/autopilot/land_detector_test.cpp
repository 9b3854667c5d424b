// SPDX-License-Identifier: BSD-3-Clause
// The emulated autopilots' land detectors against the stage conditions and trigger times of
// PX4's MulticopterLandDetector and ArduCopter's land detector (land_detector.hpp cites them).
#include "fnmpc/autopilot/land_detector.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace fnmpc::autopilot {
namespace {

constexpr double kDt = 0.01;

/// Feeds `in` from `t0` for `duration` [s]; returns the first time disarm was allowed (NaN:
/// never).
double FirstAllowed(LandDetector* d, const LandDetectorInput& in, double t0, double duration) {
  for (double t = t0; t < t0 + duration - 1e-9; t += kDt) {
    d->Update(t, in);
    if (d->disarm_allowed()) return t - t0;
  }
  return kNaN;
}

LandDetectorInput Idle() {
  LandDetectorInput in;
  in.thrust = 0.0;
  return in;
}

/// A detector armed at 0 that flew (hover thrust, climbing) until 1 s.
LandDetector Flown(AutopilotKind kind, const LandDetectorSettings& s = {}) {
  LandDetector d(kind, s);
  LandDetectorInput hover;
  hover.thrust = 0.45;
  hover.vertical_speed = 0.5;
  for (double t = 0.0; t < 1.0 - 1e-9; t += kDt) d.Update(t, hover);
  return d;
}

TEST(LandDetectorTest, Px4AllowsDisarmAfterGroundContactAndMaybeLanded) {
  LandDetector d = Flown(AutopilotKind::kPx4);
  EXPECT_FALSE(d.disarm_allowed());
  // ground contact 0.35 s, then maybe landed 0.25 s
  EXPECT_NEAR(FirstAllowed(&d, Idle(), 1.0, 2.0), 0.35 + 0.25, 2 * kDt);
  EXPECT_FALSE(d.landed());
  for (double t = 1.6; t < 1.95; t += kDt) d.Update(t, Idle());
  EXPECT_TRUE(d.landed());  // + 0.30 s
}

TEST(LandDetectorTest, Px4NeverAllowsDisarmAtHoverThrustOrWhileSinkingOrRotating) {
  const LandDetectorSettings s;
  LandDetectorInput hover = Idle();
  hover.thrust = 0.45;
  LandDetector a = Flown(AutopilotKind::kPx4, s);
  EXPECT_TRUE(std::isnan(FirstAllowed(&a, hover, 1.0, 5.0)));
  // Ground contact's thrust threshold (0.234) is passed, maybe-landed's (0.09) is not.
  LandDetectorInput low = Idle();
  low.thrust = 0.2;
  LandDetector b = Flown(AutopilotKind::kPx4, s);
  EXPECT_TRUE(std::isnan(FirstAllowed(&b, low, 1.0, 5.0)));
  LandDetectorInput sinking = Idle();
  sinking.vertical_speed = -0.3;  // above LNDMC_Z_VEL_MAX 0.25
  LandDetector c = Flown(AutopilotKind::kPx4, s);
  EXPECT_TRUE(std::isnan(FirstAllowed(&c, sinking, 1.0, 5.0)));
  LandDetectorInput rolling = Idle();
  rolling.tilt_rate = 0.4;  // 23 deg/s > LNDMC_ROT_MAX 20
  LandDetector e = Flown(AutopilotKind::kPx4, s);
  EXPECT_TRUE(std::isnan(FirstAllowed(&e, rolling, 1.0, 5.0)));
}

TEST(LandDetectorTest, Px4StagesRestartWhenAConditionFails) {
  LandDetector d = Flown(AutopilotKind::kPx4);
  for (double t = 1.0; t < 1.5; t += kDt) d.Update(t, Idle());
  LandDetectorInput bump = Idle();
  bump.vertical_speed = 0.5;
  d.Update(1.5, bump);
  EXPECT_NEAR(FirstAllowed(&d, Idle(), 1.51, 2.0), 0.6, 2 * kDt);
}

TEST(LandDetectorTest, Px4DisarmsByItselfComDisarmLandAfterLandedOrComDisarmPrfltWithoutTakeoff) {
  LandDetector d = Flown(AutopilotKind::kPx4);
  double due = kNaN;
  for (double t = 1.0; t < 6.0 && std::isnan(due); t += kDt) {
    d.Update(t, Idle());
    if (d.auto_disarm_due(t)) due = t;
  }
  EXPECT_NEAR(due - 1.0, 0.9 + 2.0, 2 * kDt);
  LandDetectorSettings never;
  never.disarm_land = -1.0;
  LandDetector n = Flown(AutopilotKind::kPx4, never);
  for (double t = 1.0; t < 6.0; t += kDt) n.Update(t, Idle());
  EXPECT_FALSE(n.auto_disarm_due(6.0));
  // Armed at 0 and never taken off: COM_DISARM_PRFLT (10 s), not COM_DISARM_LAND
  LandDetector p(AutopilotKind::kPx4, LandDetectorSettings{});
  due = kNaN;
  for (double t = 0.0; t < 12.0 && std::isnan(due); t += kDt) {
    p.Update(t, Idle());
    if (p.auto_disarm_due(t)) due = t;
  }
  EXPECT_NEAR(due, 10.0, 2 * kDt);
}

TEST(LandDetectorTest, AnArmedVehicleStartsLanded) {
  LandDetector d(AutopilotKind::kPx4, LandDetectorSettings{});
  d.Update(0.0, Idle());
  EXPECT_TRUE(d.landed());
  EXPECT_TRUE(d.disarm_allowed());
}

TEST(LandDetectorTest, ArduPilotNeedsTheLowerLimitAndNoAccelerationForOneSecond) {
  LandDetector d = Flown(AutopilotKind::kArduPilot);
  EXPECT_NEAR(FirstAllowed(&d, Idle(), 1.0, 3.0), 1.0, 2 * kDt);
  LandDetectorInput spinning = Idle();
  spinning.thrust = 0.1;
  LandDetector a = Flown(AutopilotKind::kArduPilot);
  EXPECT_TRUE(std::isnan(FirstAllowed(&a, spinning, 1.0, 5.0)));
  // A touchdown bump of 3 m/s^2 decays through the 1 Hz filter before the timer starts.
  LandDetectorInput bump = Idle();
  bump.acceleration = 3.0;
  LandDetector b = Flown(AutopilotKind::kArduPilot);
  for (double t = 1.0; t < 1.5; t += kDt) b.Update(t, bump);
  const double after = FirstAllowed(&b, Idle(), 1.5, 5.0);
  EXPECT_GT(after, 1.0 + 0.05);
  EXPECT_LT(after, 1.5);
}

TEST(LandDetectorTest, UnknownThrustNeverAllowsDisarm) {
  LandDetector d = Flown(AutopilotKind::kPx4);
  EXPECT_TRUE(std::isnan(FirstAllowed(&d, LandDetectorInput{}, 1.0, 3.0)));
}

}  // namespace
}  // namespace fnmpc::autopilot

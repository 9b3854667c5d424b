// SPDX-License-Identifier: BSD-3-Clause
// Setpoints and measurements through their MAVLink messages, both ways.
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <numbers>
#include <random>

#include "fnmpc/autopilot/measurement_messages.hpp"
#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/autopilot/setpoint.hpp"
#include "fnmpc/core/rotation.hpp"

namespace fnmpc::autopilot {
namespace {

TEST(SetpointTest, KnownAttitudesInNedFrd) {
  // Level, facing east in ENU (yaw 0) is yaw +90 deg in NED: q = (cos 45, 0, 0, sin 45)
  const auto east = ToSetAttitudeTarget({0, 0, 0, 0.5}, 1234, 7, 1);
  EXPECT_NEAR(std::abs(east.q[0]), M_SQRT1_2, 1e-6);
  EXPECT_NEAR(std::abs(east.q[3]), M_SQRT1_2, 1e-6);
  EXPECT_GT(east.q[0] * east.q[3], 0.0);
  EXPECT_NEAR(east.q[1], 0.0, 1e-7);
  EXPECT_NEAR(east.q[2], 0.0, 1e-7);
  EXPECT_EQ(east.time_boot_ms, 1234U);
  EXPECT_EQ(east.target_system, 7);
  EXPECT_EQ(east.type_mask, mav::kIgnoreBodyRates);
  EXPECT_FLOAT_EQ(east.thrust, 0.5F);
  // Nose down in FLU (pitch +0.2 about y-left) is nose down in FRD: NED pitch -0.2.
  // Facing north in ENU (yaw pi/2) is NED yaw 0, so the NED quaternion is about y only.
  const auto down = ToSetAttitudeTarget({0, 0.2, M_PI_2, 0.5}, 0, 1, 1);
  EXPECT_NEAR(down.q[3], 0.0, 1e-6);
  EXPECT_NEAR(WrapAngle(2.0 * std::atan2(down.q[2], down.q[0])), -0.2, 1e-6);
}

TEST(SetpointTest, RoundTripOfRandomAttitudes) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> tilt(-0.6, 0.6), yaw(-M_PI + 1e-3, M_PI);
  for (int i = 0; i < 500; ++i) {
    const AttitudeSetpoint s{tilt(rng), tilt(rng), yaw(rng), 0.37};
    const AttitudeSetpoint back = FromSetAttitudeTarget(ToSetAttitudeTarget(s, 0, 1, 1));
    ASSERT_TRUE(back.valid());
    EXPECT_NEAR(back.roll, s.roll, 2e-6);
    EXPECT_NEAR(back.pitch, s.pitch, 2e-6);
    EXPECT_NEAR(WrapAngle(back.yaw - s.yaw), 0.0, 2e-6);
  }
  mavlink::SetAttitudeTarget zero;  // all-zero quaternion: no attitude
  EXPECT_FALSE(FromSetAttitudeTarget(zero).valid());
}

Measurement Sample(SensorKind kind) {
  Measurement m;
  m.kind = kind;
  m.vehicle = 2;
  m.stamp = 12.345;
  m.arrival = 12.35;
  m.position = Vec3(1.5, -2.25, 0.8);
  m.euler = Vec3(0.05, -0.1, 2.5);
  m.accel = Vec3(0.3, -0.2, 9.7);
  m.gyro = Vec3(0.01, 0.02, -0.3);
  m.velocity = Vec3(0.4, -0.5, 0.1);
  m.voltage = 15.432;
  m.relative = RelativeObservation{1, 2.5, 0.7, -0.1, 0.2};
  m.yaw = 2.5;
  return m;
}

TEST(MeasurementMessagesTest, EveryCarriedKindRoundTrips) {
  for (const SensorKind k : {SensorKind::kImu, SensorKind::kMocapPose, SensorKind::kOpticalFlow,
                             SensorKind::kBattery, SensorKind::kRelative, SensorKind::kCompass}) {
    const Measurement m = Sample(k);
    mavlink::Message msg;
    ASSERT_TRUE(ToMessage(m, &msg)) << ToString(k);
    Measurement back;
    ASSERT_TRUE(FromMessage(msg, 2, 0.0, 20.0, &back)) << ToString(k);
    EXPECT_EQ(back.kind, k);
    EXPECT_EQ(back.vehicle, 2);
    EXPECT_EQ(back.arrival, 20.0);
    // Stamps: microseconds (ATTITUDE: milliseconds); SYS_STATUS has none (stamped on arrival)
    EXPECT_NEAR(back.stamp, k == SensorKind::kBattery ? 20.0 : m.stamp,
                k == SensorKind::kCompass ? 0.5e-3 : 1e-9)
        << ToString(k);
    switch (k) {
      case SensorKind::kImu:
        EXPECT_LT((back.accel - m.accel).norm(), 1e-5);
        EXPECT_LT((back.gyro - m.gyro).norm(), 1e-6);
        break;
      case SensorKind::kMocapPose:
        EXPECT_LT((back.position - m.position).norm(), 1e-6);
        EXPECT_LT((back.euler - m.euler).norm(), 2e-6);
        break;
      case SensorKind::kOpticalFlow:
        EXPECT_LT((back.velocity - m.velocity).norm(), 1e-6);
        break;
      case SensorKind::kBattery:
        EXPECT_NEAR(back.voltage, m.voltage, 0.5e-3);  // mV resolution
        break;
      case SensorKind::kRelative:
        EXPECT_EQ(back.relative.target, 1);
        EXPECT_NEAR(back.relative.range, 2.5, 1e-6);
        EXPECT_NEAR(back.relative.bearing, 0.7, 1e-6);
        EXPECT_NEAR(back.relative.elevation, -0.1, 1e-6);
        EXPECT_NEAR(back.relative.relative_yaw, 0.2, 1e-6);
        break;
      case SensorKind::kCompass:
        EXPECT_NEAR(back.yaw, 2.5, 1e-6);
        break;
      default:
        break;
    }
  }
}

TEST(MeasurementMessagesTest, FramesAreMavlinksAxes) {
  // A resting IMU reads +g up in FLU: MAVLink's FRD has it at -z
  mavlink::Message msg;
  ASSERT_TRUE(ToMessage(Sample(SensorKind::kImu), &msg));
  EXPECT_NEAR(std::get<mavlink::HighresImu>(msg).zacc, -9.7, 1e-5);
  EXPECT_NEAR(std::get<mavlink::HighresImu>(msg).yacc, 0.2, 1e-6);
  // ENU (1.5 east, -2.25 north, 0.8 up) is NED (-2.25, 1.5, -0.8)
  ASSERT_TRUE(ToMessage(Sample(SensorKind::kMocapPose), &msg));
  const auto& o = std::get<mavlink::Odometry>(msg);
  EXPECT_FLOAT_EQ(o.x, -2.25F);
  EXPECT_FLOAT_EQ(o.y, 1.5F);
  EXPECT_FLOAT_EQ(o.z, -0.8F);
  EXPECT_EQ(o.estimator_type, mav::kEstimatorMocap);
  EXPECT_TRUE(std::isnan(o.vx));
  // A heading east (ENU yaw 0) is NED yaw +pi/2 (clockwise from north); north is NED 0
  Measurement compass = Sample(SensorKind::kCompass);
  compass.yaw = 0.0;
  ASSERT_TRUE(ToMessage(compass, &msg));
  EXPECT_NEAR(std::get<mavlink::Attitude>(msg).yaw, std::numbers::pi / 2, 1e-6);
  EXPECT_TRUE(std::isnan(std::get<mavlink::Attitude>(msg).roll));
  compass.yaw = std::numbers::pi / 2;
  ASSERT_TRUE(ToMessage(compass, &msg));
  EXPECT_NEAR(std::get<mavlink::Attitude>(msg).yaw, 0.0, 1e-6);
}

TEST(MeasurementMessagesTest, WhatTheLinkDoesNotCarryIsRefused) {
  mavlink::Message msg;
  Measurement m = Sample(SensorKind::kCompass);
  m.yaw = kNaN;
  EXPECT_FALSE(ToMessage(m, &msg));
  m = Sample(SensorKind::kImu);
  m.accel.x() = kNaN;
  EXPECT_FALSE(ToMessage(m, &msg));
  m = Sample(SensorKind::kImu);
  m.stamp = -1.0;
  EXPECT_FALSE(ToMessage(m, &msg));
  // ODOMETRY of an estimator we do not read, and a NaN position
  ASSERT_TRUE(ToMessage(Sample(SensorKind::kMocapPose), &msg));
  auto odo = std::get<mavlink::Odometry>(msg);
  odo.estimator_type = 4;  // GPS
  Measurement out;
  EXPECT_FALSE(FromMessage(odo, 0, 0.0, 0.0, &out));
  odo.estimator_type = mav::kEstimatorMocap;
  odo.x = std::nanf("");
  EXPECT_FALSE(FromMessage(odo, 0, 0.0, 0.0, &out));
  EXPECT_FALSE(FromMessage(mavlink::Heartbeat{}, 0, 0.0, 0.0, &out));
  mavlink::HighresImu imu;  // fields_updated without the gyro
  imu.fields_updated = 0x7;
  EXPECT_FALSE(FromMessage(imu, 0, 0.0, 0.0, &out));
}

TEST(ClockMapTest, SmallestDelayWinsAndARebootStartsOver) {
  ClockMap c;
  EXPECT_FALSE(c.known());
  c.Observe(10.0, 110.02);
  c.Observe(10.1, 110.105);
  c.Observe(10.2, 110.23);
  EXPECT_NEAR(c.ToLocal(10.2) - 10.2, 100.005, 1e-9);
  EXPECT_EQ(c.rate(), 1.0);
  c.Observe(0.5, 111.0);  // remote clock restarted
  EXPECT_EQ(c.resets(), 1);
  EXPECT_NEAR(c.ToLocal(0.5), 111.0, 1e-9);
}

/// An autopilot clock at `rate` times the wall clock, stamps arriving after 1-20 ms of
/// random delay at 100 Hz for `duration` s: the largest error of the mapping in the last
/// minute, against the stamp's true local time plus the smallest possible delay (1 ms).
double MappingError(double rate, double duration, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> delay(0.001, 0.020);
  ClockMap c;
  double worst = 0.0;
  for (double local_sent = 0.0; local_sent < duration; local_sent += 0.01) {
    const double remote = 3.0 + rate * local_sent;  // the autopilot booted 3 s earlier
    c.Observe(remote, 50.0 + local_sent + delay(rng));
    if (local_sent > duration - 60.0) {
      worst = std::max(worst, std::abs(c.ToLocal(remote) - (50.0 + local_sent + 0.001)));
    }
  }
  return worst;
}

TEST(ClockMapTest, AutopilotClocksAtPointNineToOnePointOneTimesTheWallClockAreFollowed) {
  for (const double rate : {0.9, 0.95, 0.98, 1.0, 1.0001, 1.05, 1.1}) {
    // Over ten minutes the mapped stamp stays within 2 ms of the least-delayed arrival (an
    // offset alone would be off by |1 - rate| * 600 s: 12 s at 0.98).
    EXPECT_LT(MappingError(rate, 600.0, 7), 0.002) << "rate " << rate;
  }
}

TEST(ClockMapTest, ARebootedAutopilotAtAnotherRateIsFollowedAgain) {
  ClockMap c;
  for (double t = 0.0; t < 60.0; t += 0.01) c.Observe(100.0 + 0.95 * t, t + 0.002);
  EXPECT_NEAR(c.rate(), 1.0 / 0.95, 1e-3);
  for (double t = 60.0; t < 120.0; t += 0.01) c.Observe(1.05 * (t - 60.0), t + 0.002);
  EXPECT_EQ(c.resets(), 1);
  EXPECT_NEAR(c.rate(), 1.0 / 1.05, 1e-3);
  EXPECT_NEAR(c.ToLocal(1.05 * 59.0), 119.0 + 0.002, 1e-3);
}

}  // namespace
}  // namespace fnmpc::autopilot

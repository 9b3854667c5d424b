// SPDX-License-Identifier: BSD-3-Clause
// The neighbour thrust estimate of the wake level (neighbour_thrust.hpp): the formula and its
// bounds, and the chain the follower runs every control step (NeighbourEkf with its two modes ->
// filtered derivative of the velocity -> mixed mean acceleration -> m ||a + g e_z||) on noisy
// relative measurements of a neighbour that accelerates and of one that hovers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "fnmpc/estimation/neighbour_ekf.hpp"
#include "fnmpc/formation/neighbour_acceleration.hpp"
#include "fnmpc/formation/neighbour_thrust.hpp"

namespace fnmpc::formation {
namespace {

constexpr double kMass = 1.37;       // [kg], the shipped vehicle file's
constexpr double kMaxThrust = 25.0;  // [N], ControllerSettings::thrust_max
constexpr double kHover = kMass * kGravity;

TEST(NeighbourThrustTest, FormulaAndItsBounds) {
  // An accelerating vehicle: thrust along a + g e_z
  const Vec3 a(1.0, -0.5, 2.0);
  ThrustEstimate e = ThrustFromAcceleration(kMass, a, kMaxThrust);
  EXPECT_EQ(e.bound, ThrustBound::kNone);
  EXPECT_NEAR(e.thrust, kMass * std::sqrt(1.0 + 0.25 + (2.0 + kGravity) * (2.0 + kGravity)), 1e-12);
  // At rest: the hover thrust
  e = ThrustFromAcceleration(kMass, Vec3::Zero(), kMaxThrust);
  EXPECT_EQ(e.bound, ThrustBound::kNone);
  EXPECT_DOUBLE_EQ(e.thrust, kHover);
  // Free fall: no thrust, within the range
  e = ThrustFromAcceleration(kMass, Vec3(0.0, 0.0, -kGravity), kMaxThrust);
  EXPECT_EQ(e.bound, ThrustBound::kNone);
  EXPECT_NEAR(e.thrust, 0.0, 1e-12);
  // Faster than free fall: the thrust would point down, bounded to 0 with the reason
  e = ThrustFromAcceleration(kMass, Vec3(3.0, 0.0, -kGravity - 1.0), kMaxThrust);
  EXPECT_EQ(e.bound, ThrustBound::kUpsideDown);
  EXPECT_EQ(e.thrust, 0.0);
  // More than any vehicle of the formation can be commanded: the bound, with the reason
  e = ThrustFromAcceleration(kMass, Vec3(0.0, 0.0, 15.0), kMaxThrust);
  EXPECT_EQ(e.bound, ThrustBound::kAboveMax);
  EXPECT_EQ(e.thrust, kMaxThrust);
  // Never NaN: a non-finite acceleration gives the hover thrust, with the reason
  for (const Vec3& bad : {Vec3(kNaN, 0.0, 0.0), Vec3(0.0, kInf, 0.0), Vec3(0.0, 0.0, -kInf)}) {
    e = ThrustFromAcceleration(kMass, bad, kMaxThrust);
    EXPECT_EQ(e.bound, ThrustBound::kNonFinite);
    EXPECT_DOUBLE_EQ(e.thrust, kHover);
  }
  EXPECT_STREQ(ToString(ThrustBound::kUpsideDown), "upside_down");
  // The mixed mean acceleration: the hover mode's share is zero, one model leaves it
  EXPECT_LT((MixedAcceleration(0.25, a) - 0.75 * a).norm(), 1e-15);
  EXPECT_EQ(MixedAcceleration(kNaN, a), a);
}

struct ChainStats {
  double mean = 0.0, std = 0.0, max_dev = 0.0;  // of the thrust estimate in the window [N]
  double truth = 0.0;                           // m ||a + g e_z|| of the truth [N]
  long bounded = 0;
};

// A neighbour 2 m ahead and 0.5 m above of an observer at rest, `accel` [m/s^2] from
// t_accel on (zero before); the relative sensor at the shipped default rate and noise (50 Hz),
// the follower's chain at the control rate (20 Hz) as VehicleController runs it; statistics
// of the thrust estimate over [window_begin, window_end).
ChainStats FlyChain(const Vec3& accel, double t_accel, double window_begin, double window_end,
                    std::uint32_t seed) {
  estimation::NeighbourEkfConfig cfg;  // the defaults: two modes (hover and manoeuvre)
  cfg.observer = 0;
  cfg.target = 1;
  cfg.own_velocity_rate_hz = 20.0;
  EXPECT_GT(cfg.hover_accel_noise, 0.0);
  estimation::NeighbourEkf ekf(cfg);
  AccelerationEstimate acc(0.1, 0.125);  // ControllerSettings' filter time, 2.5 Ts gap
  std::mt19937 rng(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  const SensorSpec& spec = cfg.sensors.relative;
  const Vec3 start(2.0, 0.0, 0.5);
  constexpr double kDt = 0.01;
  double sum = 0.0, sum2 = 0.0;
  long n = 0;
  ChainStats s;
  s.truth = kMass * (accel + Vec3(0.0, 0.0, kGravity)).norm();
  for (int k = 0; k * kDt < window_end; ++k) {
    const double t = k * kDt, ta = std::max(0.0, t - t_accel);
    const Vec3 p = start + 0.5 * ta * ta * accel;
    if (k % 2 == 0) {  // 50 Hz relative sensor
      Measurement m;
      m.kind = SensorKind::kRelative;
      m.vehicle = 0;
      m.stamp = m.arrival = t;
      RelativeObservation& o = m.relative;
      o.target = 1;
      o.range = p.norm() + spec.noise.x() * (1.0 + spec.range_noise_growth * p.norm()) * nd(rng);
      o.bearing = std::atan2(p.y(), p.x()) + spec.noise.y() * nd(rng);
      o.elevation = std::asin(p.z() / p.norm()) + spec.noise.z() * nd(rng);
      o.relative_yaw = spec.noise2.x() * nd(rng);
      ekf.Process(m, Vec3::Zero(), Vec3::Zero());
    }
    if (k % 5 != 1) continue;  // 20 Hz control step
    ekf.PredictTo(t, Vec3::Zero());
    const estimation::NeighbourStateVec x = ekf.state();
    const Vec3 a = MixedAcceleration(ekf.hover_probability(), acc.Update(t, x.segment<3>(3)));
    const ThrustEstimate e = ThrustFromAcceleration(kMass, a, kMaxThrust);
    EXPECT_TRUE(std::isfinite(e.thrust));
    if (e.bound != ThrustBound::kNone) ++s.bounded;
    if (t < window_begin) continue;
    sum += e.thrust;
    sum2 += e.thrust * e.thrust;
    ++n;
    s.max_dev = std::max(s.max_dev, std::abs(e.thrust - s.truth));
  }
  s.mean = sum / n;
  s.std = std::sqrt(std::max(0.0, sum2 / n - s.mean * s.mean));
  return s;
}

TEST(NeighbourThrustTest, AcceleratingNeighbourGivesItsThrust) {
  // Given a neighbour that holds for 4 s, then accelerates at (1, -0.5, 1.5) m/s^2 (a climb
  // with a sideways start), measured by the noisy relative sensor
  const Vec3 a(1.0, -0.5, 1.5);
  for (std::uint32_t seed = 1; seed <= 5; ++seed) {
    // When the follower's chain has had 1.5 s to follow the manoeuvre (its filters' lag)
    const ChainStats s = FlyChain(a, 4.0, 5.5, 7.0, seed);
    std::printf(
        "[neighbour thrust] seed %u accelerating: estimate %.3f N (sd %.3f, max dev %.3f) vs "
        "true %.3f N (hover %.3f N)\n",
        seed, s.mean, s.std, s.max_dev, s.truth, kHover);
    // Then the estimate is the neighbour's thrust m ||a + g e_z|| (15.57 N, 2.13 N above the
    // hover thrust) on its mean within 2 % (the filters' lag is over), with the noise of the
    // manoeuvring mode's velocity differentiated over 0.1 s (about 5 %), never bounded
    EXPECT_NEAR(s.mean, s.truth, 0.02 * s.truth);
    EXPECT_LT(s.std, 0.07 * s.truth);
    EXPECT_EQ(s.bounded, 0);
  }
}

TEST(NeighbourThrustTest, NoisyHoverGivesHoverThrustWithinItsNoise) {
  // Given a neighbour that hovers, measured by the noisy relative sensor
  for (std::uint32_t seed = 1; seed <= 5; ++seed) {
    const ChainStats s = FlyChain(Vec3::Zero(), kInf, 3.0, 20.0, seed);
    std::printf(
        "[neighbour thrust] seed %u hover: estimate %.4f N (sd %.4f, max dev %.4f) vs %.4f N\n",
        seed, s.mean, s.std, s.max_dev, kHover);
    // Then the estimate is the hover thrust to within its own noise: the hover mode holds
    // the mixed mean acceleration near zero (standard deviation about 0.1 %), the mean within
    // 0.1 %, every sample within 2 %
    EXPECT_NEAR(s.mean, kHover, 1e-3 * kHover);
    EXPECT_LT(s.std, 2e-3 * kHover);
    EXPECT_LT(s.max_dev, 0.02 * kHover);
    EXPECT_EQ(s.bounded, 0);
  }
}

}  // namespace
}  // namespace fnmpc::formation

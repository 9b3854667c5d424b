// SPDX-License-Identifier: BSD-3-Clause
// Offset-free attitude: the attitude offset estimate of a plant whose attitude loop settles at
// k (ref + b) converges to k b, and the closed loop of the observer level removes the position
// offset such a bias leaves at level `none`.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "fnmpc/formation/attitude_offset.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "tests/formation/controller_test_support.hpp"

namespace fnmpc::formation {
namespace {

using testing::BaseConfig;
using testing::kGround;
using testing::kTs;
using testing::Plant;

const Vec<2> kTau(0.1203, 0.1303), kGain(1.01, 1.02);

TEST(AttitudeOffsetTest, ConvergesToTheBiasOfANoisyFirstOrderLoop) {
  // Given the model's first-order attitude loop with a level-calibration bias b (it settles
  // at k (ref + b)), random references held over each step and a noisy attitude measurement
  const Vec<2> b(0.02, -0.03);
  AttitudeOffset est(kTau, kGain, 2.0, 0.07, 2.5 * kTs);
  est.Reset();
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.002);
  std::uniform_real_distribution<double> ref_draw(-0.2, 0.2);
  Vec<2> angle = Vec<2>::Zero();
  for (int k = 0; k * kTs < 30.0; ++k) {
    est.Observe(k * kTs, angle + Vec<2>(noise(rng), noise(rng)));
    const Vec<2> ref(ref_draw(rng), ref_draw(rng));
    est.Sent(ref);
    for (int i = 0; i < 2; ++i) {
      const double a = std::exp(-kTs / kTau[i]);
      angle[i] = a * angle[i] + (1.0 - a) * kGain[i] * (ref[i] + b[i]);
    }
  }
  // Then after 30 s (15 filter time constants) the estimate is k b within 1.5 mrad (the
  // residual's noise, 0.002 (1 + a^2)^0.5 / (1 - a) ~ 0.007 rad, averaged over 2 s)
  std::printf("[attitude offset] estimate (%.5f, %.5f) rad, k b (%.5f, %.5f) rad\n",
              est.offset()[0], est.offset()[1], kGain[0] * b[0], kGain[1] * b[1]);
  EXPECT_NEAR(est.offset()[0], kGain[0] * b[0], 1.5e-3);
  EXPECT_NEAR(est.offset()[1], kGain[1] * b[1], 1.5e-3);
  EXPECT_FALSE(est.bounded());
  EXPECT_NEAR(est.reference_offset()[0], b[0], 1.5e-3);
}

TEST(AttitudeOffsetTest, InvalidSamplesNeverReachTheEstimateAndItIsBounded) {
  AttitudeOffset est(kTau, kGain, 0.5, 0.05, 2.5 * kTs);
  est.Reset();
  // A non-finite angle, a missing reference, a gap and a second reference update nothing.
  est.Observe(0.0, Vec<2>(kNaN, 0.0));
  est.Sent(Vec<2>(0.0, 0.0));
  est.Observe(kTs, Vec<2>(0.3, 0.3));      // previous angle unknown
  est.Observe(2 * kTs, Vec<2>(0.3, 0.3));  // no reference sent in between
  est.Sent(Vec<2>(0.0, 0.0));
  est.Observe(10.0, Vec<2>(0.3, 0.3));  // gap
  est.Sent(Vec<2>(kNaN, 0.0));
  est.Observe(10.0 + kTs, Vec<2>(0.3, 0.3));  // non-finite reference
  EXPECT_TRUE(est.offset().isZero());
  // The first valid interval moves it.
  est.Sent(Vec<2>(0.0, 0.0));
  est.Observe(10.0 + 2 * kTs, Vec<2>(0.3, 0.3));
  EXPECT_GT(est.offset()[0], 0.0);
  EXPECT_GT(est.offset()[1], 0.0);
  const Vec<2> before = est.offset();
  est.Sent(Vec<2>(0.0, 0.0));
  est.Sent(Vec<2>(0.0, 0.0));  // two references for one interval: unusable
  est.Observe(10.0 + 3 * kTs, Vec<2>(0.9, 0.9));
  EXPECT_EQ(est.offset(), before);
  // A held offset larger than the bound is cut at it, and that is said.
  for (int k = 4; k < 200; ++k) {
    est.Sent(Vec<2>(0.0, 0.0));
    est.Observe(10.0 + k * kTs, Vec<2>(0.3, -0.3));
  }
  EXPECT_DOUBLE_EQ(est.offset()[0], 0.05);
  EXPECT_DOUBLE_EQ(est.offset()[1], -0.05);
  EXPECT_TRUE(est.bounded());
}

// The NMPC's model as plant with an autopilot level-calibration bias b: its attitude loop
// tracks k (ref + b) (sim::World's autopilot), the estimate measures the true attitude and
// reports no external force (d is evaluated at the measured attitude, so a bias gives none).
struct BiasedPlant {
  Plant plant;
  Vec<2> bias = Vec<2>::Zero();
  void Step(const ControlOutput& u) {
    ControlOutput biased = u;
    biased.roll += bias[0];
    biased.pitch += bias[1];
    plant.Step(biased);
  }
};

struct Hover {
  double error = kNaN;             // final distance from the hover point [m]
  Vec<2> offset = Vec<2>::Zero();  // final attitude offset estimate [rad]
  bool bounded_beyond_limit = false;
};

Hover HoldWithBias(Compensation level, const Vec<2>& bias, double until) {
  ControllerConfig cfg = BaseConfig(true);
  cfg.compensation = level;
  VehicleController c(cfg);
  BiasedPlant p;
  Hover h;
  for (int k = 0; k * kTs <= until; ++k) {
    // The bias acts from the NMPC's hold on (the PID take-off holds no position model).
    p.bias = c.phase() == FlightPhase::kNmpc && k * kTs > 4.0 ? bias : Vec<2>(Vec<2>::Zero());
    const ControlOutput o = c.ControlWithEstimates(k * kTs, p.plant.Estimate(k * kTs), {});
    // The reference sent stays within its bound, never clamped.
    if (std::abs(o.roll) > cfg.max_attitude_ref + 1e-9 ||
        std::abs(o.pitch) > cfg.max_attitude_ref + 1e-9) {
      h.bounded_beyond_limit = true;
    }
    if (o.nmpc) h.offset = o.attitude_offset;
    p.Step(o);
  }
  EXPECT_EQ(c.phase(), FlightPhase::kNmpc);
  EXPECT_EQ(c.fallbacks(), 0);
  h.error = (p.plant.x.head<3>() - c.anchor()).norm();
  return h;
}

TEST(AttitudeOffsetTest, ObserverLevelRemovesTheOffsetOfAnAttitudeBias) {
  // Given a hovering leader whose autopilot has 1.5 deg roll and -2 deg pitch biases from 4 s
  const Vec<2> bias(0.026, -0.035);
  // When it holds its hover point for 20 s with each level
  const Hover none = HoldWithBias(Compensation::kNone, bias, 24.0);
  const Hover observer = HoldWithBias(Compensation::kObserver, bias, 24.0);
  std::printf(
      "[attitude offset] steady hover error: none %.4f m, observer %.5f m; estimate "
      "(%.4f, %.4f) rad, k b (%.4f, %.4f) rad\n",
      none.error, observer.error, observer.offset[0], observer.offset[1], kGain[0] * bias[0],
      kGain[1] * bias[1]);
  // Then without the estimate the bias holds the vehicle off its point; with it the offset
  // is gone and the estimate is the bias through the model's gain
  EXPECT_GT(none.error, 0.01);
  EXPECT_LT(observer.error, 0.1 * none.error);
  EXPECT_NEAR(observer.offset[0], kGain[0] * bias[0], 2e-3);
  EXPECT_NEAR(observer.offset[1], kGain[1] * bias[1], 2e-3);
  EXPECT_TRUE(none.offset.isZero());  // `none` estimates nothing
  EXPECT_FALSE(none.bounded_beyond_limit);
  EXPECT_FALSE(observer.bounded_beyond_limit);
}

TEST(AttitudeOffsetTest, ReferenceSentStaysWithinItsBoundAtTheLimit) {
  // Given a leader whose bounds leave 0.05 rad of attitude reference and a 2 deg bias, so
  // that holding the point needs the whole correction at the bound's edge
  ControllerConfig cfg = BaseConfig(true);
  cfg.compensation = Compensation::kObserver;
  cfg.max_attitude_ref = 0.05;
  cfg.attitude_offset_max = 0.04;
  VehicleController c(cfg);
  BiasedPlant p;
  double worst = 0.0;
  for (int k = 0; k * kTs <= 20.0; ++k) {
    p.bias = c.phase() == FlightPhase::kNmpc ? Vec<2>(0.035, 0.035) : Vec<2>(Vec<2>::Zero());
    const ControlOutput o = c.ControlWithEstimates(k * kTs, p.plant.Estimate(k * kTs), {});
    if (o.nmpc) worst = std::max({worst, std::abs(o.roll), std::abs(o.pitch)});
    p.Step(o);
  }
  // Then the reference sent never leaves +-max_attitude_ref (the NMPC's bounds moved)
  EXPECT_LE(worst, cfg.max_attitude_ref + 1e-9);
  EXPECT_EQ(c.fallbacks(), 0);
}

}  // namespace
}  // namespace fnmpc::formation

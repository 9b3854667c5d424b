// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/propulsion.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

namespace fnmpc::sysid {
namespace {

model::ThrottlePolynomial ShippedPolynomial() {
  model::ThrottlePolynomial p;
  p.c << 1.295532269, -0.1703711916, 0.008857434141, -0.0001635235747, 0.2929197223, -0.01461840844,
      0.0002619815754, 0.0, -0.01292856667, 0.0002213855606, 0.0, 0.0, 0.0003812494858, 0.0, 0.0,
      0.0;
  return p;
}

BenchData Synthesise(const model::ThrottlePolynomial& poly, double tk, double tq, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  BenchData b;
  for (double v = 14.6; v < 16.85; v += 0.2) {
    for (double u = 0.2; u < 1.001; u += 0.04) {
      const double f = poly.Thrust(u, v);
      if (!(f > 0.0)) continue;
      const double w = std::sqrt(f / tk);
      b.throttle.push_back(u);
      b.voltage.push_back(v + 0.01 * n(rng));
      b.rpm.push_back(w + 5.0 * n(rng));
      b.thrust.push_back(f * (1.0 + 0.002 * n(rng)) + 0.01 * n(rng));
      b.torque.push_back(tq * w * w * (1.0 + 0.005 * n(rng)) + 2e-4 * n(rng));
    }
  }
  return b;
}

TEST(PropulsionTest, RecoversConstantsAndPolynomialFromNoisyBench) {
  // Given thrust-stand data of a known propulsion with sensor noise,
  const model::ThrottlePolynomial truth = ShippedPolynomial();
  const BenchData bench = Synthesise(truth, 9.803e-8, 1.507e-9, 3);
  // When the propulsion is fitted,
  const PropulsionFit fit = FitPropulsion(bench);
  // Then the constants are within 1 % and the throttle within 0.02 over the flight envelope.
  EXPECT_NEAR(fit.thrust_constant, 9.803e-8, 0.01 * 9.803e-8);
  EXPECT_NEAR(fit.torque_constant, 1.507e-9, 0.01 * 1.507e-9);
  double worst = 0.0;
  for (double f = 2.0; f <= 8.0; f += 0.25) {
    for (double v = 15.0; v <= 16.8; v += 0.1) {
      worst = std::max(worst, std::abs(fit.throttle.Throttle(f, v) - truth.Throttle(f, v)));
    }
  }
  EXPECT_LT(worst, 0.02);
  EXPECT_LT(fit.throttle_rms, 0.01);
  EXPECT_EQ(fit.samples, static_cast<int>(bench.rpm.size()));
}

TEST(PropulsionTest, RejectsBadInput) {
  // Given bench data with one short column or a single voltage,
  BenchData b = Synthesise(ShippedPolynomial(), 9.803e-8, 1.507e-9, 4);
  BenchData shorter = b;
  shorter.torque.pop_back();
  BenchData one_voltage = b;
  for (double& v : one_voltage.voltage) v = 16.0;
  // When / Then the fit refuses them.
  EXPECT_THROW(FitPropulsion(shorter), std::invalid_argument);
  EXPECT_THROW(FitPropulsion(one_voltage), std::invalid_argument);
  EXPECT_THROW(FitPropulsion(BenchData{}), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::sysid

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/pendulum.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

namespace fnmpc::sysid {
namespace {

TEST(PendulumTest, BifilarFormulaAndInverseAgree) {
  // Given the bifilar formula I = m g d^2 T^2 / (16 pi^2 L),
  const double m = 1.37, d = 0.3, L = 1.0, inertia = 0.0123;
  // When a period is computed from an inertia and back,
  const double T = BifilarPeriod(m, d, L, inertia);
  // Then the inertia is recovered and the period matches the formula by hand.
  EXPECT_NEAR(BifilarInertia(m, d, L, T), inertia, 1e-15);
  EXPECT_NEAR(T, std::sqrt(inertia * 16.0 * M_PI * M_PI * L / (m * 9.81 * d * d)), 1e-12);
  EXPECT_THROW(BifilarInertia(0.0, d, L, T), std::invalid_argument);
}

TEST(PendulumTest, PeriodOfNoisyDampedSwingWithOutliers) {
  // Given a slightly damped swing with jittered sample times, noise and spikes,
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0.0, 0.003);
  std::uniform_real_distribution<double> u(-0.002, 0.002);
  const double period = 1.234, lambda = 0.05;
  const double wn = 2.0 * M_PI / period, wd = std::sqrt(wn * wn - lambda * lambda);
  std::vector<double> t, a;
  for (int k = 0; k < 2000; ++k) {
    const double tk = 0.01 * k + u(rng);
    t.push_back(tk);
    double y = 0.2 * std::exp(-lambda * tk) * std::cos(wd * tk + 0.7) + 0.01 + n(rng);
    if (k % 97 == 13) y -= 0.08;
    a.push_back(y);
  }
  // When the swing is fitted,
  const PendulumFit fit = FitPendulum(t, a);
  // Then the natural period is within 0.2 % and the decay within 20 %.
  EXPECT_NEAR(fit.natural_period, period, 0.002 * period);
  EXPECT_NEAR(fit.decay_rate, lambda, 0.2 * lambda);
  EXPECT_NEAR(fit.offset, 0.01, 0.002);
  EXPECT_GT(fit.damped_period, fit.natural_period);
}

TEST(PendulumTest, RejectsTooShortRecords) {
  // Given 10 samples, When fitted, Then the fit refuses.
  std::vector<double> t(10), a(10);
  for (int k = 0; k < 10; ++k) t[k] = 0.1 * k;
  EXPECT_THROW(FitPendulum(t, a), std::invalid_argument);
  EXPECT_THROW(FitPendulum(t, std::vector<double>(9)), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::sysid

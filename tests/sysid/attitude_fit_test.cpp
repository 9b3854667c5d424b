// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/attitude_fit.hpp"
#include "fnmpc/sysid/angles.hpp"
#include "fnmpc/sysid/trajectory_fit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

namespace fnmpc::sysid {
namespace {

// Step/doublet reference sampled at 250 Hz: 0, +a, 0, -a, 0 (1.2 s each).
void StepLog(double amplitude, std::vector<double>* t, std::vector<double>* ref) {
  const std::array<double, 5> levels{0.0, 1.0, 0.0, -1.0, 0.0};
  for (int k = 0; k < 1500; ++k) {
    t->push_back(0.004 * k);
    ref->push_back(amplitude * levels[static_cast<std::size_t>(k / 300)]);
  }
}

TEST(AttitudeFitTest, FirstOrderWithDelayIsRecovered) {
  // Given a first-order response with a 15 ms delay, noise and a few outliers,
  std::vector<double> t, ref, y;
  StepLog(0.1, &t, &ref);
  SimulateFirstOrder<double>(t, ref, 0.12, 1.02, 0.0, 0.015, 0.003, &y);
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 0.001);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] += n(rng) + (i % 211 == 7 ? 0.03 : 0.0);
  // When it is fitted,
  const FirstOrderFit fit = FitFirstOrder(t, ref, y);
  // Then tau, k and the delay are recovered.
  EXPECT_NEAR(fit.time_constant, 0.12, 0.003);
  EXPECT_NEAR(fit.gain, 1.02, 0.005);
  EXPECT_NEAR(fit.delay, 0.015, 0.002);
  EXPECT_NEAR(fit.equivalent_time_constant, 0.135, 0.004);
  EXPECT_LT(fit.rms, 0.003);
}

TEST(AttitudeFitTest, PdGainsOfTheLightModelAreRecovered) {
  // Given the light-weight loop with known gains, logged with noise,
  std::vector<double> t, ref, y;
  StepLog(0.1, &t, &ref);
  const AttitudeLoopSettings st;
  SimulateAttitudeLoop<double>(t, ref, 0.99, 420.0, 48.0, 0.0, st, &y);
  std::mt19937 rng(6);
  std::normal_distribution<double> n(0.0, 0.001);
  for (double& v : y) v += n(rng);
  // When first-order model and PD gains are fitted,
  const FirstOrderFit fo = FitFirstOrder(t, ref, y);
  const PdFit pd = FitPdGains(t, ref, y, fo, st);
  // Then the gains are within 3 % and the loop's mean residence time K_d/K_p is close to
  // the first-order equivalent time constant.
  EXPECT_NEAR(pd.kp, 420.0, 0.03 * 420.0);
  EXPECT_NEAR(pd.kd, 48.0, 0.03 * 48.0);
  EXPECT_NEAR(fo.gain, 0.99, 0.01);
  EXPECT_NEAR(fo.equivalent_time_constant, 48.0 / 420.0, 0.08 * 48.0 / 420.0);
  EXPECT_LT(pd.rms, 0.0015);
}

TEST(AttitudeFitTest, PdGainsWithTransportDelayAt100HzConverge) {
  // Given the light-weight loop behind a 20 ms transport delay, logged at 100 Hz with the
  // reference held on the logging grid and 3 mrad noise (the held-out campaign's setting
  // where the fit used to diverge),
  std::vector<double> t, ref, y;
  const std::array<double, 5> levels{0.0, 1.0, 0.0, -1.0, 0.0};
  for (int k = 0; k < 3000; ++k) {  // five doublets, 30 s
    t.push_back(0.01 * k);
    ref.push_back(0.1 * levels[static_cast<std::size_t>(k / 120) % 5]);
  }
  AttitudeLoopSettings truth;
  truth.delay = 0.02;
  SimulateAttitudeLoop<double>(t, ref, 1.02, 420.0, 48.0, 0.0, truth, &y);
  std::mt19937 rng(8);
  std::normal_distribution<double> n(0.0, 0.003);
  for (double& v : y) v += n(rng);
  // When first-order model and PD gains (with their own delay) are fitted,
  const FirstOrderFit fo = FitFirstOrder(t, ref, y);
  const PdFit pd = FitPdGains(t, ref, y, fo, AttitudeLoopSettings{});
  // Then the fit converges to finite gains near the truth, finds the delay, and the
  // standard errors are finite.
  EXPECT_NEAR(pd.kp, 420.0, 0.1 * 420.0);
  EXPECT_NEAR(pd.kd, 48.0, 0.1 * 48.0);
  EXPECT_NEAR(pd.delay, 0.02, 0.0025);
  EXPECT_TRUE(std::isfinite(pd.kp_std_error) && std::isfinite(pd.kd_std_error));
  EXPECT_FALSE(pd.at_bound);
  EXPECT_LT(pd.rms, 0.0045);
}

// A model that diverges (NaN) for p > 2: y = exp(p t) on t in [0, 1].
struct Diverging {
  const std::vector<double>* t;
  template <class T>
  void operator()(const T* p, std::vector<T>* y) const {
    using std::exp;
    y->resize(t->size());
    for (std::size_t i = 0; i < t->size(); ++i) {
      (*y)[i] = p[0] > T(2.0) ? T(std::numeric_limits<double>::quiet_NaN()) : exp(p[0] * (*t)[i]);
    }
  }
};

TEST(AttitudeFitTest, TrajectoryFitRejectsDivergedSimulations) {
  // Given data of p = 1.9 and a model that diverges beyond p = 2,
  std::vector<double> t, y;
  for (int k = 0; k <= 50; ++k) {
    t.push_back(0.02 * k);
    y.push_back(std::exp(1.9 * t.back()));
  }
  const Diverging sim{&t};
  // When fitted from p = 1 with a bound far inside the diverged region,
  const auto r = FitTrajectory<1>(sim, y, {1.0}, {0.0}, {100.0}, 0.0);
  // Then the diverged trial steps are rejected and the fit converges to the truth;
  EXPECT_TRUE(r.converged);
  EXPECT_NEAR(r.p[0], 1.9, 1e-6);
  // and a start inside the diverged region fails cleanly instead of returning NaN.
  const auto bad = FitTrajectory<1>(sim, y, {3.0}, {0.0}, {100.0}, 0.0);
  EXPECT_FALSE(bad.converged);
}

TEST(AttitudeFitTest, RejectsConstantReference) {
  // Given a log whose reference never changes, When fitted, Then the fit refuses.
  std::vector<double> t(100), ref(100, 0.1), y(100, 0.1);
  for (int k = 0; k < 100; ++k) t[k] = 0.01 * k;
  EXPECT_THROW(FitFirstOrder(t, ref, y), std::invalid_argument);
  EXPECT_THROW(FitFirstOrder(t, ref, std::vector<double>(99)), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::sysid

namespace fnmpc::sysid {
namespace {

TEST(UnwrapAnglesTest, ContinuousAcrossPiAndFiniteForAbsurdValues) {
  // Given a yaw that crosses +-pi and one absurd sample (a loop stepping by 2 pi never ends),
  const std::vector<double> a{3.0, -3.0, -2.9, 1e17, 3.1};
  // When unwrapped, Then the crossing is continuous and every value is finite.
  const auto u = UnwrapAngles(a);
  EXPECT_NEAR(u[1], -3.0 + 2.0 * M_PI, 1e-12);
  EXPECT_NEAR(u[2], -2.9 + 2.0 * M_PI, 1e-12);
  for (double x : u) EXPECT_TRUE(std::isfinite(x));
  EXPECT_LE(std::abs(u[3] - u[2]), M_PI + 1e-9);
  EXPECT_NEAR(UnwrapNear(-3.0, 3.0), -3.0 + 2.0 * M_PI, 1e-12);
}

}  // namespace
}  // namespace fnmpc::sysid

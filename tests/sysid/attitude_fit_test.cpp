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

TEST(AttitudeFitTest, GapsAreFoundAndTheWindowAfterThemIsLeftOut) {
  // Given 100 Hz time stamps with 0.30 s missing after t = 2.00 s,
  std::vector<double> t;
  for (int k = 0; k < 500; ++k) {
    const double tk = 0.01 * k;
    if (tk > 2.005 && tk < 2.295) continue;
    t.push_back(tk);
  }
  // When the gaps are looked for,
  const std::vector<Gap> gaps = FindGaps(t, 1.5);
  // Then there is one, from the last sample before to the first after it,
  ASSERT_EQ(gaps.size(), 1U);
  EXPECT_NEAR(gaps[0].start, 2.00, 1e-9);
  EXPECT_NEAR(gaps[0].end, 2.30, 1e-9);
  EXPECT_NEAR(t[gaps[0].index], 2.30, 1e-9);
  // and the mask leaves out exactly the samples in (2.00, 2.30 + 0.5].
  const SampleMask use = GapMask(t, gaps, 0.5);
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_EQ(use[i] == 0, t[i] > 2.0 + 1e-9 && t[i] <= 2.8 + 1e-9) << "t = " << t[i];
  }
  EXPECT_THROW(FindGaps(t, 1.0), std::invalid_argument);
}

TEST(AttitudeFitTest, ReferenceChangeInsideAGapDoesNotBiasTheMaskedFit) {
  // Given a first-order response with a 15 ms delay whose log loses 0.25 s around the
  // reference change at 2.4 s (the held reference then changes at the end of the gap),
  std::vector<double> t_all, ref_all, y_all, t, ref, y;
  StepLog(0.1, &t_all, &ref_all);
  SimulateFirstOrder<double>(t_all, ref_all, 0.12, 1.02, 0.0, 0.015, 0.0, &y_all);
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0.0, 0.001);
  for (std::size_t i = 0; i < t_all.size(); ++i) {
    if (t_all[i] > 2.30 && t_all[i] < 2.55) continue;
    t.push_back(t_all[i]);
    ref.push_back(ref_all[i]);
    y.push_back(y_all[i] + n(rng));
  }
  // When it is fitted with the window after the gap left out, and without,
  FirstOrderFitSettings masked;
  masked.use = GapMask(t, FindGaps(t, 1.5), 0.5);
  const FirstOrderFit with_mask = FitFirstOrder(t, ref, y, masked);
  const FirstOrderFit without = FitFirstOrder(t, ref, y);
  // Then the masked fit recovers tau and the delay; the unmasked one is further off.
  EXPECT_NEAR(with_mask.time_constant, 0.12, 0.003);
  EXPECT_NEAR(with_mask.delay, 0.015, 0.002);
  EXPECT_GT(std::abs(without.time_constant - 0.12) + std::abs(without.delay - 0.015),
            2.0 * (std::abs(with_mask.time_constant - 0.12) + std::abs(with_mask.delay - 0.015)));
}

TEST(AttitudeFitTest, SegmentFoldsAlternateAfterTheFirstSegment) {
  // Given the step log (reference changes every 1.2 s),
  std::vector<double> t, ref;
  StepLog(0.1, &t, &ref);
  // When it is cut into segments of at least 1 s,
  int segments = 0;
  const auto fold = SegmentFolds(t, ref, 1.0, &segments);
  // Then there are five, the first in both training sets (2), then 1, 0, 1, 0.
  EXPECT_EQ(segments, 5);
  const std::array<int, 5> want{2, 1, 0, 1, 0};
  for (std::size_t i = 0; i < t.size(); ++i) EXPECT_EQ(fold[i], want[i / 300]) << i;
  // and with 2 s segments the changes 1.2 s apart are merged in pairs.
  SegmentFolds(t, ref, 2.0, &segments);
  EXPECT_EQ(segments, 3);
}

TEST(AttitudeFitTest, HeldOutValidationPrefersTheStructureThatMadeTheData) {
  // Given a pure dead time + first-order response (40 ms, 0.1 s) and the PD loop with a
  // 5 ms delay, both logged at 250 Hz with 1 mrad noise over two doublets,
  std::vector<double> t, ref;
  const std::array<double, 5> levels{0.0, 1.0, 0.0, -1.0, 0.0};
  for (int k = 0; k < 2500; ++k) {
    t.push_back(0.004 * k);
    ref.push_back(0.1 * levels[static_cast<std::size_t>(k / 250) % 5]);
  }
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0.0, 0.001);
  std::vector<double> y_fo, y_pd;
  SimulateFirstOrder<double>(t, ref, 0.10, 1.0, 0.0, 0.040, 0.0, &y_fo);
  AttitudeLoopSettings st;
  st.delay = 0.005;
  SimulateAttitudeLoop<double>(t, ref, 1.0, 420.0, 48.0, 0.0, st, &y_pd);
  for (auto* y : {&y_fo, &y_pd}) {
    for (double& v : *y) v += n(rng);
  }
  // When both structures are cross-validated on held-out segments,
  const AttitudeLoopSettings loop;
  const HeldOutValidation a = ValidateOnHeldOutSegments(t, ref, y_fo, {}, loop, 0.9);
  const HeldOutValidation b = ValidateOnHeldOutSegments(t, ref, y_pd, {}, loop, 0.9);
  // Then each fold prefers the true structure by more than 5 % in held-out RMS,
  EXPECT_TRUE(a.pd_error.empty()) << a.pd_error;
  EXPECT_TRUE(b.pd_error.empty()) << b.pd_error;
  for (int f = 0; f < 2; ++f) {
    EXPECT_GT(a.fold_margin[f], 0.05) << "first-order data, fold " << f;
    EXPECT_LT(b.fold_margin[f], -0.05) << "PD-loop data, fold " << f;
  }
  // and the true structure predicts the held-out segments to better than 95 %.
  EXPECT_GT(a.first_order_fit_percent, 95.0);
  EXPECT_GT(b.pd_fit_percent, 95.0);
  EXPECT_EQ(a.segments, 9);  // ten levels, the fifth and sixth both 0
}

}  // namespace
}  // namespace fnmpc::sysid

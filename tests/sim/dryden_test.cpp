// SPDX-License-Identifier: BSD-3-Clause
// Dryden turbulence against the closed forms of MIL-F-8785C / MIL-HDBK-1797.
#include "fnmpc/sim/dryden.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <vector>

namespace fnmpc::sim {
namespace {

DrydenSettings Example() {
  DrydenSettings s;
  s.sigma = Vec3(1.2, 0.9, 0.6);
  s.length_scale = Vec3(30.0, 20.0, 8.0);
  s.airspeed = 4.0;
  return s;
}

TEST(DrydenTest, LowAltitudeModelMatchesTheSpecificationFormulas) {
  // MIL-F-8785C low altitude at h = 50 ft, W20 = 30 kt (moderate): in feet,
  // L_w = 50, L_u = L_v = 50 / (0.177 + 0.000823 * 50)^1.2 = 310.8 ft,
  // sigma_w = 3 kt, sigma_u = sigma_v = 3 kt / (0.21815)^0.4 = 5.52 kt.
  const double kt = 0.514444, ft = 0.3048;
  const DrydenSettings s = LowAltitudeDryden(30.0 * kt, 50.0 * ft, 10.0);
  EXPECT_NEAR(s.length_scale.z(), 50.0 * ft, 1e-9);
  EXPECT_NEAR(s.length_scale.x() / ft, 50.0 / std::pow(0.21815, 1.2), 1e-6);
  EXPECT_NEAR(s.length_scale.x() / ft, 310.8, 0.1);
  EXPECT_NEAR(s.sigma.z(), 3.0 * kt, 1e-12);
  EXPECT_NEAR(s.sigma.x() / kt, 5.52, 0.01);
  EXPECT_EQ(s.sigma.x(), s.sigma.y());
  EXPECT_THROW(LowAltitudeDryden(5.0, 1.0, 1.0), std::invalid_argument);  // below 10 ft
}

TEST(DrydenTest, SpectraIntegrateToTheVarianceAndTransformToTheAutocorrelation) {
  // The one-sided spectra integrate to sigma^2 and their cosine transforms are the
  // closed-form autocorrelations (Wiener-Khinchin), by quadrature in x = atan(L w / V).
  const DrydenSettings s = Example();
  for (int axis = 0; axis < 3; ++axis) {
    const double scale = s.airspeed / s.length_scale[axis];
    for (double tau : {0.0, 0.5, 2.0, 7.0}) {
      const int n = 400000;
      double integral = 0.0;
      for (int k = 0; k < n; ++k) {
        const double x = (k + 0.5) * (M_PI / 2) / n;  // omega = scale tan(x)
        const double omega = scale * std::tan(x);
        const double jac = scale / (std::cos(x) * std::cos(x));
        integral += DrydenSpectrum(s, axis, omega) * std::cos(omega * tau) * jac * (M_PI / 2) / n;
      }
      EXPECT_NEAR(integral, DrydenAutocorrelation(s, axis, tau),
                  2e-3 * s.sigma[axis] * s.sigma[axis])
          << "axis " << axis << " tau " << tau;
    }
    EXPECT_DOUBLE_EQ(DrydenAutocorrelation(s, axis, 0.0), s.sigma[axis] * s.sigma[axis]);
  }
}

TEST(DrydenTest, DiscreteFilterHasTheClosedFormAutocorrelationExactly) {
  // The discretised v and w filters: the stationary state covariance P solves the
  // discrete Lyapunov equation, and c^T Phi^k P c equals R(k dt) of the spectrum.
  const DrydenSettings s = Example();
  const double dt = 0.01;
  DrydenTurbulence turb(s, dt, 1);
  for (int axis = 1; axis < 3; ++axis) {
    const Eigen::Matrix2d p = turb.StationaryCovariance(axis);
    const double t = s.length_scale[axis] / s.airspeed;
    const double k = s.sigma[axis] * std::sqrt(s.length_scale[axis] / (M_PI * s.airspeed));
    const Eigen::Vector2d c = k * Eigen::Vector2d(std::sqrt(3.0), 1.0 - std::sqrt(3.0));
    EXPECT_NEAR(c.dot(p * c), s.sigma[axis] * s.sigma[axis], 1e-12);
    Eigen::Matrix2d phi;
    const double e = std::exp(-dt / t);
    phi << e, 0.0, e * dt / t, e;
    Eigen::Matrix2d pk = p;
    for (int lag = 0; lag <= 2000; ++lag) {
      if (lag % 250 == 0) {
        EXPECT_NEAR(c.dot(pk * c), DrydenAutocorrelation(s, axis, lag * dt), 1e-10)
            << "axis " << axis << " lag " << lag;
      }
      pk = phi * pk;
    }
  }
}

TEST(DrydenTest, SampledTurbulenceHasTheSpecifiedVarianceAndCorrelation) {
  // Long sampled sequences: variance within 5 % of sigma^2 and the autocorrelation at
  // one scale time within 0.05 sigma^2 of the closed form.
  const DrydenSettings s = Example();
  const double dt = 0.05;
  const int n = 400000;  // 20000 s = 2500 scale times of L_u / V
  DrydenTurbulence turb(s, dt, 5);
  std::vector<Vec3> x(n);
  for (int k = 0; k < n; ++k) x[k] = turb.Step();
  for (int axis = 0; axis < 3; ++axis) {
    const int lag = static_cast<int>(std::lround(s.length_scale[axis] / s.airspeed / dt));
    double var = 0.0, cov = 0.0, mean = 0.0;
    for (int k = 0; k < n; ++k) mean += x[k][axis] / n;
    for (int k = 0; k < n; ++k) var += (x[k][axis] - mean) * (x[k][axis] - mean) / n;
    for (int k = 0; k + lag < n; ++k)
      cov += (x[k][axis] - mean) * (x[k + lag][axis] - mean) / (n - lag);
    const double s2 = s.sigma[axis] * s.sigma[axis];
    EXPECT_NEAR(var, s2, 0.05 * s2) << "axis " << axis;
    EXPECT_NEAR(cov, DrydenAutocorrelation(s, axis, lag * dt), 0.05 * s2) << "axis " << axis;
  }
}

}  // namespace
}  // namespace fnmpc::sim

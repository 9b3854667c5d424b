// SPDX-License-Identifier: BSD-3-Clause
// NeighbourEkf with the neighbour (almost) straight above the observer: the bearing
// atan2(dy, dx) of the relative sensor is singular there. The Cartesian update must stay
// bounded for every vertical separation and horizontal offset; the legacy spherical update
// is run on the same data for comparison.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cstdio>
#include <random>

#include "fnmpc/estimation/neighbour_ekf.hpp"
#include "synthetic_truth.hpp"

namespace fnmpc::estimation {
namespace {

using Idx = NeighbourStateIndex;

struct OverheadCase {
  double dz = 0.5;      // neighbour height above the observer [m]
  double offset = 0.0;  // horizontal offset [m]
  double wobble = 0.0;  // observer roll/pitch oscillation amplitude [rad]
  std::uint32_t seed = 1;
};

struct OverheadResult {
  double max_error = 0.0;  // largest |dx error| after the first second [m]
  double max_std = 0.0;    // largest sqrt(eigenvalue of P_dx) after the first second [m]
  double rms_error = 0.0;  // [m]
  bool finite = true;      // state and covariance finite throughout
  bool valid_at_end = false;
  std::int64_t gated = 0, numerical = 0, measurements = 0;
};

// 10 s hover: the observer at rest (level, or rocking by `wobble`), the neighbour at rest at
// (offset along a fixed direction, dz above). Relative sensor at 50 Hz with the default noise
// (config/sensors/default.yaml = SensorsConfig{}), elevation clamped to +-90 deg as the
// simulator does; own attitude passed with 2 mrad white error and its covariance; PredictTo
// at 100 Hz as in the controller.
OverheadResult RunOverhead(const OverheadCase& c, RelativeUpdate update) {
  NeighbourEkfConfig cfg;
  cfg.relative_update = update;
  const SensorSpec& spec = cfg.sensors.relative;
  NeighbourEkf ekf(cfg);
  std::mt19937 rng(c.seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  const double dir = 0.7;
  const Vec3 truth(c.offset * std::cos(dir), c.offset * std::sin(dir), c.dz);
  const double psi_j = 1.0;
  constexpr double kOwnAttitudeStd = 0.002;
  const Mat3 own_cov = Mat3::Identity() * kOwnAttitudeStd * kOwnAttitudeStd;
  OverheadResult r;
  double err2 = 0.0;
  int n_err = 0;
  for (int k = 0; k <= 1000; ++k) {
    const double t = 0.01 * k;
    if (k % 2 == 1) {
      const Vec3 euler(c.wobble * std::sin(2.1 * t), c.wobble * std::cos(1.7 * t), 0.4);
      Measurement m;
      m.kind = SensorKind::kRelative;
      m.vehicle = 0;
      m.stamp = t;
      m.relative = testing::TrueRelative(Vec3::Zero(), euler, truth, psi_j, 1);
      RelativeObservation& o = m.relative;
      o.range += spec.noise.x() * (1.0 + spec.range_noise_growth * o.range) * nd(rng);
      o.bearing = WrapAngle(o.bearing + spec.noise.y() * nd(rng));
      o.elevation = std::clamp(o.elevation + spec.noise.z() * nd(rng), -M_PI / 2, M_PI / 2);
      o.relative_yaw = WrapAngle(o.relative_yaw + spec.noise2.x() * nd(rng));
      const Vec3 own_euler = euler + testing::Gaussian3(&rng, Vec3::Constant(kOwnAttitudeStd));
      ekf.Process(m, own_euler, Vec3::Zero(), &own_cov);
      ++r.measurements;
    } else {
      ekf.PredictTo(t, Vec3::Zero());
    }
    if (!ekf.initialized()) continue;
    const NeighbourStateVec x = ekf.state();
    const Mat3 P = ekf.covariance().topLeftCorner<3, 3>();
    if (!x.allFinite() || !P.allFinite()) {
      r.finite = false;
      break;
    }
    if (t >= 1.0) {
      const double e = (x.segment<3>(Idx::kRelPos) - truth).norm();
      r.max_error = std::max(r.max_error, e);
      err2 += e * e;
      ++n_err;
      const double max_eig = Eigen::SelfAdjointEigenSolver<Mat3>(P).eigenvalues().maxCoeff();
      r.max_std = std::max(r.max_std, std::sqrt(std::max(max_eig, 0.0)));
    }
  }
  r.rms_error = n_err > 0 ? std::sqrt(err2 / n_err) : kInf;
  r.valid_at_end = ekf.EstimateAt(10.0, Vec3::Zero()).valid;
  r.gated = ekf.counters().Get(EkfStatus::kRejectedGated, SensorKind::kRelative);
  r.numerical = ekf.counters().Get(EkfStatus::kNumericalError, SensorKind::kRelative);
  return r;
}

TEST(RelativeOverheadTest, CartesianUpdateBoundedStraightAboveAndNear) {
  // Given vertical separations 0.3-1.5 m, horizontal offsets 0, 1 mm, 1 cm, 0.3 m, a level and
  // a rocking observer, 6 noise seeds each, the default relative sensor
  // (the filtered std is about 1.3 cm along the line of sight: 6 sigma, and 2 cm RMS)
  constexpr double kMaxError = 0.08;  // [m]
  constexpr double kMaxRms = 0.02;    // [m]
  constexpr double kMaxStd = 0.03;    // [m]
  int cases = 0, new_bad = 0, old_bad = 0;
  double new_worst = 0.0, old_worst = 0.0;
  for (double dz : {0.3, 0.5, 1.0, 1.5}) {
    for (double offset : {0.0, 0.001, 0.01, 0.3}) {
      double row_new = 0.0, row_old = 0.0, row_std = 0.0, row_rms = 0.0;
      for (double wobble : {0.0, 0.02}) {
        for (std::uint32_t seed = 1; seed <= 6; ++seed) {
          const OverheadCase c{dz, offset, wobble, seed};
          // When filtered with the Cartesian (default) and the legacy spherical update
          const OverheadResult n = RunOverhead(c, RelativeUpdate::kCartesian);
          const OverheadResult o = RunOverhead(c, RelativeUpdate::kSpherical);
          ++cases;
          // Then the Cartesian estimate is finite, within a few cm, its covariance small and
          // the estimate valid; no measurement is lost to numerics, hardly any to the gate
          SCOPED_TRACE(::testing::Message() << "dz " << dz << " offset " << offset << " wobble "
                                            << wobble << " seed " << seed);
          EXPECT_TRUE(n.finite);
          EXPECT_LT(n.max_error, kMaxError);
          EXPECT_LT(n.rms_error, kMaxRms);
          EXPECT_LT(n.max_std, kMaxStd);
          EXPECT_TRUE(n.valid_at_end);
          EXPECT_EQ(n.numerical, 0);
          EXPECT_LE(n.gated, n.measurements / 100);
          const bool nb = !n.finite || !(n.max_error < kMaxError);
          const bool ob = !o.finite || !(o.max_error < kMaxError) || o.numerical > 0;
          new_bad += nb ? 1 : 0;
          old_bad += ob ? 1 : 0;
          row_new = std::max(row_new, n.max_error);
          row_old = std::max(row_old, o.finite ? o.max_error : kInf);
          row_std = std::max(row_std, n.max_std);
          row_rms = std::max(row_rms, n.rms_error);
        }
      }
      new_worst = std::max(new_worst, row_new);
      old_worst = std::max(old_worst, row_old);
      std::printf(
          "[overhead] dz %.1f m offset %.3f m: cartesian max error %.4f m, worst rms %.4f m, "
          "max std %.4f m; spherical max error %.4g m\n",
          dz, offset, row_new, row_rms, row_std, row_old);
    }
  }
  std::printf(
      "[overhead] %d runs: cartesian %d beyond %.2f m (worst %.4f m), spherical %d (worst %.4g "
      "m)\n",
      cases, new_bad, kMaxError, new_worst, old_bad, old_worst);
  EXPECT_EQ(new_bad, 0);
  // And the legacy spherical update, on the same data, is worse
  EXPECT_GT(old_bad, 0);
  EXPECT_GT(old_worst, new_worst);
}

TEST(RelativeOverheadTest, ConvertedCovarianceMatchesSampledSpread) {
  // Given relative observations with the default noise, generic and straight above
  const SensorSpec spec = SensorsConfig{}.relative;
  std::mt19937 rng(7);
  std::normal_distribution<double> nd(0.0, 1.0);
  const Vec3 own_euler(0.05, -0.03, 0.4);
  const Mat3 own_cov = Mat3::Identity() * 4e-6;
  for (const Vec3& offset : {Vec3(2.0, 1.0, 0.4), Vec3(0.0, 0.0, 0.8), Vec3(0.001, 0.0, 0.5)}) {
    const RelativeObservation truth =
        testing::TrueRelative(Vec3::Zero(), own_euler, offset, 1.0, 1);
    Vec<4> z0;
    Mat<4, 4> R;
    RelativeToCartesian(truth, own_euler, own_cov, spec, &z0, &R);
    // When converting 40000 noisy observations (noisy own attitude too, no clamping)
    constexpr int kN = 40000;
    Vec<4> mean = Vec<4>::Zero();
    Mat<4, 4> cov = Mat<4, 4>::Zero();
    std::vector<Vec<4>> samples(kN);
    for (auto& s : samples) {
      RelativeObservation o = truth;
      o.range += spec.noise.x() * (1.0 + spec.range_noise_growth * o.range) * nd(rng);
      o.bearing += spec.noise.y() * nd(rng);
      o.elevation += spec.noise.z() * nd(rng);
      o.relative_yaw += spec.noise2.x() * nd(rng);
      const Vec3 e = own_euler + testing::Gaussian3(&rng, Vec3::Constant(0.002));
      Mat<4, 4> unused;
      RelativeToCartesian(o, e, Mat3::Zero(), spec, &s, &unused);
      s(3) = z0(3) + WrapAngle(s(3) - z0(3));
      mean += s / kN;
    }
    for (const auto& s : samples) cov += (s - mean) * (s - mean).transpose() / (kN - 1);
    // Then the mean is the noise-free conversion and R matches the sampled covariance
    // (relative Frobenius error 5 %; 40000 samples give about 1 %), also straight above,
    // where R stays positive definite
    SCOPED_TRACE(::testing::Message() << "offset " << offset.transpose());
    EXPECT_LT((mean.head<3>() - offset).norm(), 1e-3);
    EXPECT_LT((cov - R).norm(), 0.05 * R.norm());
    const double min_eig = Eigen::SelfAdjointEigenSolver<Mat<4, 4>>(R).eigenvalues().minCoeff();
    EXPECT_GT(min_eig, 0.0);
  }
}

}  // namespace
}  // namespace fnmpc::estimation

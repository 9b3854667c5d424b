// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/core/sin_cos.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "fnmpc/core/rotation.hpp"

namespace fnmpc {
namespace {

// Distance of a from b in units in the last place of b.
double Ulps(double a, double b) {
  const double ulp =
      std::nextafter(std::abs(b), std::numeric_limits<double>::infinity()) - std::abs(b);
  return std::abs(a - b) / ulp;
}

TEST(SinCosTest, SeriesWithinOneUlpOfTheLibraryOnTheQuarterCircle) {
  // Given uniformly drawn angles within pi/4, some of them tiny
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(-M_PI / 4.0, M_PI / 4.0);
  double worst_sin = 0.0, worst_cos = 0.0;
  for (int i = 0; i < 200000; ++i) {
    const double x = i % 4 == 0 ? 1e-4 * angle(rng) : angle(rng);
    double s = 0.0, c = 0.0;
    SinCos(x, &s, &c);
    worst_sin = std::max(worst_sin, Ulps(s, std::sin(x)));
    worst_cos = std::max(worst_cos, Ulps(c, std::cos(x)));
  }
  // Then the inline series differs from std::sin and std::cos by at most 1 ulp
  EXPECT_LE(worst_sin, 1.0);
  EXPECT_LE(worst_cos, 1.0);
}

TEST(SinCosTest, EndpointsZeroAndLibraryBeyondTheQuarterCircle) {
  double s = 1.0, c = 0.0;
  SinCos(0.0, &s, &c);
  EXPECT_EQ(s, 0.0);
  EXPECT_EQ(c, 1.0);
  for (const double x : {M_PI / 4.0, -M_PI / 4.0}) {
    SinCos(x, &s, &c);
    EXPECT_LE(Ulps(s, std::sin(x)), 1.0) << x;
    EXPECT_LE(Ulps(c, std::cos(x)), 1.0) << x;
  }
  // Beyond pi/4 (a yaw of 3 rad, a large angle): the library's values, bit for bit
  for (const double x : {0.7854, -1.2, 3.0, -3.1, 100.0, 1e6}) {
    SinCos(x, &s, &c);
    EXPECT_EQ(s, std::sin(x)) << x;
    EXPECT_EQ(c, std::cos(x)) << x;
  }
  SinCos(std::numeric_limits<double>::quiet_NaN(), &s, &c);
  EXPECT_TRUE(std::isnan(s) && std::isnan(c));
  SinCos(std::numeric_limits<double>::infinity(), &s, &c);
  EXPECT_TRUE(std::isnan(s) && std::isnan(c));
}

TEST(SinCosTest, BodyZAndJacobianAgreesWithTheTemplatedBodyZ) {
  // The body z axis from the series (BodyZAndJacobian) against BodyZ on std::sin/std::cos
  for (const double phi : {-0.6, -0.1, 0.0, 0.02, 0.35}) {
    for (const double psi : {-3.0, -0.5, 0.0, 0.3, 2.5}) {
      Eigen::Vector3d z;
      Eigen::Matrix3d dz;
      BodyZAndJacobian(phi, -0.7 * phi + 0.05, psi, &z, &dz);
      const Eigen::Vector3d ref = BodyZ<double>(phi, -0.7 * phi + 0.05, psi);
      EXPECT_LT((z - ref).cwiseAbs().maxCoeff(), 4e-16) << phi << " " << psi;
    }
  }
}

}  // namespace
}  // namespace fnmpc

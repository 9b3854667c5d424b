// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "fnmpc/core/rotation.hpp"

namespace fnmpc {
namespace {

// The definition WrapAngle keeps: std::remainder by 2 pi, -pi moved to pi.
double WrapByRemainder(double a) {
  a = std::remainder(a, 2.0 * M_PI);
  return a <= -M_PI ? a + 2.0 * M_PI : a;
}

TEST(WrapAngleTest, BitIdenticalToTheRemainderInsideAndOutsideTheHalfOpenCircle) {
  // Given angles drawn inside (-pi, pi], up to 10 turns away, and the edges with their neighbours
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> inside(-M_PI, M_PI), outside(-20 * M_PI, 20 * M_PI);
  std::vector<double> angles = {0.0, -0.0, M_PI, -M_PI, 2 * M_PI, -2 * M_PI, 3 * M_PI, 1e300};
  for (double edge : {M_PI, -M_PI}) {
    angles.push_back(std::nextafter(edge, 0.0));
    angles.push_back(std::nextafter(edge, 2.0 * edge));
  }
  for (int i = 0; i < 100000; ++i) angles.push_back(i % 2 == 0 ? inside(rng) : outside(rng));
  for (double a : angles) {
    // Then the wrapped angle has the same bits as the remainder's, and lies in (-pi, pi]
    const double w = WrapAngle(a);
    EXPECT_EQ(std::signbit(w), std::signbit(WrapByRemainder(a))) << a;
    EXPECT_EQ(w, WrapByRemainder(a)) << a;
    EXPECT_GT(w, -M_PI) << a;
    EXPECT_LE(w, M_PI) << a;
  }
  EXPECT_EQ(WrapAngle(-M_PI), M_PI);
  EXPECT_TRUE(std::isnan(WrapAngle(std::numeric_limits<double>::quiet_NaN())));
  EXPECT_TRUE(std::isnan(WrapAngle(std::numeric_limits<double>::infinity())));
}

}  // namespace
}  // namespace fnmpc

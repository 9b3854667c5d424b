// SPDX-License-Identifier: BSD-3-Clause
// The controller's wake model (fnmpc/model/wake_force.hpp): gradients against central finite
// differences like every model, symmetry, decay, no NaN anywhere.
#include "fnmpc/model/wake_force.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/support/numeric_jacobian.hpp"

namespace fnmpc::model {
namespace {

constexpr double kHover = 1.37 * kGravity;  // the shipped vehicle's hover thrust [N]

TEST(WakeForceModelTest, GradientsMatchFiniteDifferences) {
  const WakeForceModel wake;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> lateral(-1.0, 1.0), vertical(-0.3, 3.0);
  int checked = 0;
  // Random points, the rotor-plane onset, the axis itself (r_x = r_y = 0).
  std::vector<Vec3> points = {Vec3(0.0, 0.0, -0.8), Vec3(0.0, 0.0, 0.0), Vec3(0.1, -0.2, -0.02),
                              Vec3(0.0, 0.0, 0.03), Vec3(0.4, 0.0, -1.5)};
  for (int i = 0; i < 40; ++i) points.emplace_back(lateral(rng), lateral(rng), -vertical(rng));
  for (const Vec3& r : points) {
    for (const double thrust : {0.5 * kHover, kHover, 25.0}) {
      Vec3 grad;
      const double a = wake.Acceleration(r, thrust, &grad);
      EXPECT_DOUBLE_EQ(a, wake.Acceleration(r, thrust));  // the same value without the gradient
      const auto f = [&](const Vec3& x) { return Vec<1>(wake.Acceleration(x, thrust)); };
      const Vec3 fd = ::fnmpc::testing::NumericJacobian<3>(r, f).transpose();
      EXPECT_LT((fd - grad).cwiseAbs().maxCoeff(), 1e-6 * std::max(1.0, fd.norm()))
          << "r = " << r.transpose() << ", T = " << thrust;
      Vec3 gu;
      wake.Velocity(r, thrust, &gu);
      const auto fu = [&](const Vec3& x) { return Vec<1>(wake.Velocity(x, thrust)); };
      EXPECT_LT(
          (::fnmpc::testing::NumericJacobian<3>(r, fu).transpose() - gu).cwiseAbs().maxCoeff(),
          1e-6 * std::max(1.0, gu.norm()));
      ++checked;
    }
  }
  EXPECT_EQ(checked, 135);
  // The thrust ratio's derivative in the inflow.
  for (const double u : {0.0, 1.0, 3.0, 6.0}) {
    double d = 0.0;
    wake.ThrustRatio(u, &d);
    EXPECT_NEAR(d, (wake.ThrustRatio(u + 1e-6) - wake.ThrustRatio(u - 1e-6)) / 2e-6, 1e-6);
  }
}

TEST(WakeForceModelTest, StillAirAndDirection) {
  const WakeForceModel wake;
  EXPECT_NEAR(wake.ThrustRatio(0.0), 1.0, 1e-12);  // the identified static thrust is kept
  EXPECT_LT(wake.ThrustRatio(3.0), wake.ThrustRatio(1.0));
  // Below: pushed down; above the rotor plane and without thrust: nothing.
  EXPECT_LT(wake.Acceleration(Vec3(0.0, 0.0, -1.0), kHover), -1.0);
  // (the smooth onset leaves 1/500 of the push at 0.8 m below 0.3 m above the rotor plane)
  EXPECT_NEAR(wake.Acceleration(Vec3(0.0, 0.0, 0.3), kHover), 0.0, 0.01);
  EXPECT_NEAR(wake.Acceleration(Vec3(0.0, 0.0, 1.0), kHover), 0.0, 1e-6);
  EXPECT_NEAR(wake.Acceleration(Vec3(0.0, 0.0, -1.0), 0.0), 0.0, 1e-12);
  // Side by side at the formation spacing: nothing.
  EXPECT_NEAR(wake.Acceleration(Vec3(1.5, 0.0, 0.0), kHover), 0.0, 1e-4);
}

TEST(WakeForceModelTest, SymmetricAboutTheAxis) {
  const WakeForceModel wake;
  for (const double z : {-0.5, -1.0, -2.0}) {
    const double ref = wake.Acceleration(Vec3(0.3, 0.0, z), kHover);
    for (int k = 1; k < 8; ++k) {
      const double phi = k * M_PI / 4.0;
      EXPECT_NEAR(wake.Acceleration(Vec3(0.3 * std::cos(phi), 0.3 * std::sin(phi), z), kHover), ref,
                  1e-12);
    }
    Vec3 grad;
    wake.Acceleration(Vec3(0.0, 0.0, z), kHover, &grad);
    EXPECT_EQ(grad.x(), 0.0);  // on the axis: no lateral gradient
    EXPECT_EQ(grad.y(), 0.0);
  }
}

TEST(WakeForceModelTest, DecaysWithDistance) {
  const WakeForceModel wake;
  // Down the axis beyond the near field and away from it sideways: |a| falls monotonically.
  double last = wake.Acceleration(Vec3(0.0, 0.0, -0.5), kHover);
  for (double s = 0.75; s <= 20.0; s += 0.25) {
    const double a = wake.Acceleration(Vec3(0.0, 0.0, -s), kHover);
    EXPECT_GT(a, last) << s;  // negative and shrinking in magnitude
    last = a;
  }
  EXPECT_GT(last, 0.2 * wake.Acceleration(Vec3(0.0, 0.0, -1.0), kHover));  // 20 m against 1 m
  last = wake.Acceleration(Vec3(0.0, 0.0, -1.0), kHover);
  for (double x = 0.1; x <= 3.0; x += 0.1) {
    const double a = wake.Acceleration(Vec3(x, 0.0, -1.0), kHover);
    EXPECT_GT(a, last) << x;
    last = a;
  }
  EXPECT_NEAR(last, 0.0, 1e-6);
  // More thrust, more push.
  EXPECT_LT(wake.Acceleration(Vec3(0.0, 0.0, -1.0), 20.0),
            wake.Acceleration(Vec3(0.0, 0.0, -1.0), kHover));
}

// Where the wake is below double precision (a neighbour beside at the formation spacing, or
// below the follower) the model is exactly zero without evaluating it; just inside that
// region it is already below 1e-15 m/s, so nothing of size is dropped.
TEST(WakeForceModelTest, NegligibleWakeIsExactlyZeroAndWasBelowDoublePrecision) {
  const WakeForceModel wake;
  for (const Vec3& r :
       {Vec3(4.0, 0.0, 0.0), Vec3(1.7, 3.8, -0.3), Vec3(0.0, 0.0, 1.9), Vec3(0.2, 0.0, 3.0)}) {
    Vec3 grad(1.0, 1.0, 1.0);
    EXPECT_EQ(wake.Velocity(r, 40.0, &grad), 0.0) << r.transpose();
    EXPECT_EQ(grad, Vec3::Zero());
    EXPECT_EQ(wake.Velocity(r, 40.0), 0.0);
  }
  // Walk outwards from the axis (and upwards from the rotor plane): the last value before
  // the exact zero is below 1e-15 m/s, the first one is zero, and it stays zero.
  for (const double depth : {0.0, 0.5, 2.0}) {
    double last = 0.0;
    int zeros = 0;
    for (double x = 0.0; x < 10.0; x += 0.01) {
      const double u = wake.Velocity(Vec3(x, 0.0, -depth), 40.0);
      if (u == 0.0) {
        ++zeros;
      } else {
        EXPECT_EQ(zeros, 0) << "non-zero again at x = " << x;
        last = u;
      }
    }
    EXPECT_GT(zeros, 0) << depth;
    EXPECT_GT(last, 0.0);
    EXPECT_LT(last, 1e-15) << depth;
  }
  double last = 0.0;
  for (double up = 0.0; up < 5.0; up += 0.005) {
    const double u = wake.Velocity(Vec3(0.0, 0.0, up), 40.0);
    if (u == 0.0) break;
    last = u;
  }
  EXPECT_GT(last, 0.0);
  EXPECT_LT(last, 1e-15);
}

TEST(WakeForceModelTest, FiniteEverywhere) {
  const WakeForceModel wake;
  for (const Vec3& r : {Vec3(0.0, 0.0, 0.0), Vec3(0.0, 0.0, -1e-12), Vec3(0.0, 0.0, 1e6),
                        Vec3(0.0, 0.0, -1e6), Vec3(1e6, -1e6, 0.0), Vec3(1e3, 0.0, -1e3)}) {
    for (const double thrust : {0.0, kHover, 40.0}) {
      Vec3 grad;
      const double a = wake.Acceleration(r, thrust, &grad);
      EXPECT_TRUE(std::isfinite(a) && grad.allFinite()) << r.transpose() << " T " << thrust;
    }
  }
}

}  // namespace
}  // namespace fnmpc::model

// SPDX-License-Identifier: BSD-3-Clause
// The generic RK4 interval map of fnmpc/core/rk4.hpp: its sensitivities against central
// differences (the RTI solver's problem contract relies on them, tests/rti).
#include "fnmpc/core/rk4.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/support/numeric_jacobian.hpp"

namespace fnmpc {
namespace {

TEST(IntegrateRk4Test, SensitivitiesMatchFiniteDifferences) {
  // Given a pendulum, x = [angle, rate], u = [torque]
  auto flow = [](const Vec<2>& s, const Vec<1>& u, Vec<2>* f, Mat<2, 2>* fx, Mat<2, 1>* fu) {
    *f << s[1], -9.81 * std::sin(s[0]) - 0.3 * s[1] + u[0];
    if (fx != nullptr) *fx << 0.0, 1.0, -9.81 * std::cos(s[0]), -0.3;
    if (fu != nullptr) *fu << 0.0, 1.0;
  };
  const Vec<2> x0(0.7, -0.4);
  const Vec<1> u(0.5);
  // When the interval map is differentiated by IntegrateRk4 and by central differences
  Mat<2, 2> A;
  Mat<2, 1> B;
  const Vec<2> x1 = IntegrateRk4(flow, x0, u, 0.1, 3, &A, &B);
  const auto ax = testing::NumericJacobian<2>(
      x0, [&](const Vec<2>& x) { return IntegrateRk4(flow, x, u, 0.1, 3); });
  const auto bu = testing::NumericJacobian<1>(
      u, [&](const Vec<1>& v) { return IntegrateRk4(flow, x0, v, 0.1, 3); });
  // Then they agree, and the map is the same with or without sensitivities
  EXPECT_LT((A - ax).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT((B - bu).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_EQ(x1, IntegrateRk4(flow, x0, u, 0.1, 3));
}

}  // namespace
}  // namespace fnmpc

// SPDX-License-Identifier: BSD-3-Clause
// WithWake (fnmpc/ocp/wake_extension.hpp): the interval map's sensitivities against central
// finite differences like every model, the wrapped map when no slot has thrust, and the
// structured products of WakeCoupledModel against the dense transition matrix.
#include "fnmpc/ocp/wake_extension.hpp"

#include <gtest/gtest.h>

#include <random>

#include "fnmpc/ocp/problem_extensions.hpp"
#include "fnmpc/ocp/problems.hpp"
#include "fnmpc/rti/problem_contract.hpp"
#include "tests/support/numeric_jacobian.hpp"

namespace fnmpc::ocp {
namespace {

using Obst = WithObstacles<ReducedFollowerProblem<1>, 2>;
using Rate = WithInputRate<Obst>;
using Wake = WithWake<Rate, 3>;
using Full = WithAcceleration<Wake>;  // the follower's problem of the controllers
static_assert(rti::detail::HasStructuredTransition<Full::Model>::value,
              "the structured products are kept");

constexpr double kHover = 1.37 * kGravity;

// A state near a hover below neighbour 0 (in its wake), neighbour 1 beside, slot 2 unused.
void RandomCase(std::mt19937* rng, Vec<Full::kNx>* x, Vec3* u, Full::Params* p) {
  std::uniform_real_distribution<double> U(-0.3, 0.3);
  for (int i = 0; i < Full::kNx; ++i) (*x)[i] = U(*rng);
  (*x)[Full::kNx - 3] += 13.0;  // the previous thrust near hover
  *u = Vec3(13.0 + U(*rng), U(*rng), U(*rng));
  for (int i = 0; i < Full::kNp; ++i) (*p)[i] = 3.0 * U(*rng);
  p->segment<3>(Wake::ParamSource(0)) = x->head<3>() + Vec3(U(*rng), U(*rng), 0.8 + U(*rng));
  (*p)[Wake::ParamThrust(0)] = kHover + 10.0 * U(*rng);
  p->segment<3>(Wake::ParamSource(1)) = x->head<3>() + Vec3(1.0, U(*rng), U(*rng));
  (*p)[Wake::ParamThrust(1)] = kHover;
  Wake::SetUnused(2, p);
}

TEST(WakeExtensionTest, SensitivitiesMatchFiniteDifferences) {
  std::mt19937 rng(23);
  const Full prob{Wake(Rate(Obst(ReducedFollowerProblem<1>{}, 0.45)))};
  const double dt = 0.05;
  const int steps = 2;
  for (int trial = 0; trial < 20; ++trial) {
    Vec<Full::kNx> x;
    Vec3 u;
    Full::Params p;
    RandomCase(&rng, &x, &u, &p);
    Mat<Full::kNx, Full::kNx> A = Mat<Full::kNx, Full::kNx>::Zero();
    Mat<Full::kNx, Full::kNu> B = Mat<Full::kNx, Full::kNu>::Zero();
    const Vec<Full::kNx> next = prob.Discretise(x, u, p, dt, steps, &A, &B);
    EXPECT_EQ(next, prob.Discretise(x, u, p, dt, steps, nullptr, nullptr));
    using ::fnmpc::testing::NumericJacobian;
    const auto map_x = [&](const Vec<Full::kNx>& z) {
      return prob.Discretise(z, u, p, dt, steps, nullptr, nullptr);
    };
    const auto map_u = [&](const Vec3& v) {
      return prob.Discretise(x, v, p, dt, steps, nullptr, nullptr);
    };
    EXPECT_LT((NumericJacobian<Full::kNx>(x, map_x) - A).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_LT((NumericJacobian<3>(u, map_u) - B).cwiseAbs().maxCoeff(), 1e-6);
    // The wake couples the position to the vertical rows (the follower is in a wake here).
    EXPECT_GT((A.block<1, 3>(5, 0).cwiseAbs().maxCoeff()), 1e-4);
  }
}

TEST(WakeExtensionTest, WakeAddsItsAccelerationHeldOverTheInterval) {
  std::mt19937 rng(29);
  const Rate rate(Obst(ReducedFollowerProblem<1>{}, 0.45));
  const Wake prob(rate);
  const double dt = 0.05;
  Vec<Full::kNx> xf;
  Vec3 u;
  Full::Params pf;
  RandomCase(&rng, &xf, &u, &pf);
  const Vec<Wake::kNx> x = xf;
  Wake::Params p = pf.head<Wake::kNp>();
  Mat<Wake::kNx, Wake::kNx> A = Mat<Wake::kNx, Wake::kNx>::Zero(), A0 = A;
  Mat<Wake::kNx, Wake::kNu> B = Mat<Wake::kNx, Wake::kNu>::Zero(), B0 = B;
  const auto next = prob.Discretise(x, u, p, dt, 2, &A, &B);
  const auto plain = rate.Discretise(x, u, p.head<Rate::kNp>(), dt, 2, &A0, &B0);
  // The wake pushes down by the model's acceleration at the start of the interval.
  const Vec3 pos = x.head<3>();
  const double a =
      prob.wake.Acceleration(pos - p.segment<3>(Wake::ParamSource(0)), p[Wake::ParamThrust(0)]) +
      prob.wake.Acceleration(pos - p.segment<3>(Wake::ParamSource(1)), p[Wake::ParamThrust(1)]);
  EXPECT_LT(a, -1.0);
  Vec<Wake::kNx> shift = Vec<Wake::kNx>::Zero();
  shift[2] = 0.5 * dt * dt * a;
  shift[5] = dt * a;
  EXPECT_LT((next - plain - shift).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_EQ(B, B0);
  // Without thrust in any slot the map and its sensitivities are the wrapped ones, bit for bit.
  for (int o = 0; o < Wake::kSlots; ++o) Wake::SetUnused(o, &p);
  Mat<Wake::kNx, Wake::kNx> A1 = Mat<Wake::kNx, Wake::kNx>::Zero();
  Mat<Wake::kNx, Wake::kNu> B1 = Mat<Wake::kNx, Wake::kNu>::Zero();
  EXPECT_EQ(prob.Discretise(x, u, p, dt, 2, &A1, &B1), plain);
  EXPECT_EQ(A1, A0);
  EXPECT_EQ(B1, B0);
}

TEST(WakeExtensionTest, StructuredProductsEqualDenseOnes) {
  std::mt19937 rng(31);
  const Full prob{Wake(Rate(Obst(ReducedFollowerProblem<1>{}, 0.45)))};
  using M = Full::Model;
  constexpr int n = Full::kNx;
  Vec<n> x;
  Vec3 u;
  Full::Params p;
  RandomCase(&rng, &x, &u, &p);
  Mat<n, n> A = Mat<n, n>::Zero();
  Mat<n, 3> B = Mat<n, 3>::Zero();
  prob.Discretise(x, u, p, 0.05, 2, &A, &B);
  const Mat<n, 3> in = Mat<n, 3>::Random();
  const Mat<3, n> in_right = Mat<3, n>::Random();
  Mat<n, 3> out;
  M::MultiplyTransition(A, in, &out);
  EXPECT_LT((out - A * in).cwiseAbs().maxCoeff(), 1e-12);
  M::MultiplyTransitionTransposed(A, in, &out);
  EXPECT_LT((out - A.transpose() * in).cwiseAbs().maxCoeff(), 1e-12);
  Mat<3, n> out_right;
  M::MultiplyTransitionRight(in_right, A, &out_right);
  EXPECT_LT((out_right - in_right * A).cwiseAbs().maxCoeff(), 1e-12);
}

}  // namespace
}  // namespace fnmpc::ocp

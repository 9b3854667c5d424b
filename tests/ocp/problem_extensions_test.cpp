// SPDX-License-Identifier: BSD-3-Clause
// WithObstacles, WithInputRate and InputMemoryModel: values and Jacobians against central
// finite differences, like every model; the wrapped problem's residuals pass unchanged.
#include "fnmpc/ocp/problem_extensions.hpp"

#include <gtest/gtest.h>

#include <random>

#include "fnmpc/core/rk4.hpp"
#include "fnmpc/ocp/problems.hpp"
#include "tests/support/numeric_jacobian.hpp"

namespace fnmpc::ocp {
namespace {

using Obst = WithObstacles<ReducedFollowerProblem<2>, 3>;
using Full = WithInputRate<Obst>;

template <class P>
void CheckJacobians(const P& prob, const Vec<P::kNx>& x, const Vec<P::kNu>& u,
                    const Vec<P::kNp>& p) {
  using ::fnmpc::testing::NumericJacobian;
  Vec<P::kNy> y;
  Mat<P::kNy, P::kNx> yx = Mat<P::kNy, P::kNx>::Zero();
  Mat<P::kNy, P::kNu> yu = Mat<P::kNy, P::kNu>::Zero();
  prob.StageResidual(x, u, p, &y, &yx, &yu);
  const auto stage_x = [&](const Vec<P::kNx>& z) {
    Vec<P::kNy> r;
    prob.StageResidual(z, u, p, &r, nullptr, nullptr);
    return r;
  };
  const auto stage_u = [&](const Vec<P::kNu>& v) {
    Vec<P::kNy> r;
    prob.StageResidual(x, v, p, &r, nullptr, nullptr);
    return r;
  };
  EXPECT_LT((NumericJacobian<P::kNx>(x, stage_x) - yx).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((NumericJacobian<P::kNu>(u, stage_u) - yu).cwiseAbs().maxCoeff(), 1e-6);
  Vec<P::kNyN> yn;
  Mat<P::kNyN, P::kNx> ynx = Mat<P::kNyN, P::kNx>::Zero();
  prob.TerminalResidual(x, p, &yn, &ynx);
  const auto terminal = [&](const Vec<P::kNx>& z) {
    Vec<P::kNyN> r;
    prob.TerminalResidual(z, p, &r, nullptr);
    return r;
  };
  EXPECT_LT((NumericJacobian<P::kNx>(x, terminal) - ynx).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(ProblemExtensionsTest, JacobiansMatchFiniteDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-0.3, 0.3);
  Full prob(Obst(ReducedFollowerProblem<2>{}, 0.45));
  for (int trial = 0; trial < 20; ++trial) {
    Vec<Full::kNx> x;
    for (int i = 0; i < Full::kNx; ++i) x[i] = U(rng);
    const Vec3 u(13.0 + U(rng), U(rng), U(rng));
    Vec<Full::kNp> p;
    for (int i = 0; i < Full::kNp; ++i) p[i] = 3.0 * U(rng);
    // Obstacle 0 inside the radius (active), 1 outside, 2 unused.
    p.segment<3>(Obst::ParamObstacle(0)) = x.head<3>() + Vec3(0.2, -0.1, 0.05);
    p.segment<3>(Obst::ParamNormal(0)) = Vec3(0.2, -0.1, 0.05).normalized();
    p.segment<3>(Obst::ParamObstacle(1)) = x.head<3>() + Vec3(1.0, 0.4, 0.0);
    p.segment<3>(Obst::ParamNormal(1)) = Vec3(1.0, 0.4, 0.0).normalized();
    Obst::SetUnused(2, &p);
    CheckJacobians(prob, x, u, p);
  }
}

TEST(ProblemExtensionsTest, ResidualsExtendTheWrappedProblem) {
  const ReducedFollowerProblem<2> base{};
  const Full prob(Obst(base, 0.5));
  Vec<Full::kNx> x = Vec<Full::kNx>::Zero();
  x.head<3>() = Vec3(0.1, 0.2, 0.3);
  x.tail<3>() = Vec3(13.0, 0.01, -0.02);  // the previous input
  const Vec3 u(13.5, 0.05, -0.02);
  Vec<Full::kNp> p = Vec<Full::kNp>::Zero();
  p.head<ReducedFollowerProblem<2>::kNp>().setConstant(0.7);
  p.segment<3>(Obst::ParamObstacle(0)) = x.head<3>() + Vec3(0.3, 0.0, 0.0);  // 0.2 inside
  p.segment<3>(Obst::ParamNormal(0)) = Vec3(1.0, 0.0, 0.0);
  p.segment<3>(Obst::ParamObstacle(1)) = x.head<3>() + Vec3(0.0, 0.0, 0.6);  // outside
  p.segment<3>(Obst::ParamNormal(1)) = Vec3(0.0, 0.0, 1.0);
  Obst::SetUnused(2, &p);
  Vec<Full::kNy> y;
  prob.StageResidual(x, u, p, &y, nullptr, nullptr);
  Vec<ReducedFollowerProblem<2>::kNy> yb;
  base.StageResidual(x.head<9>(), u, p.head<ReducedFollowerProblem<2>::kNp>(), &yb, nullptr,
                     nullptr);
  const int nb = ReducedFollowerProblem<2>::kNy;
  EXPECT_TRUE(y.head(nb).isApprox(yb));
  EXPECT_NEAR(y[nb], -0.2, 1e-12);  // the violation of the radius
  EXPECT_EQ(y[nb + 1], 0.0);
  EXPECT_EQ(y[nb + 2], 0.0);
  EXPECT_TRUE(y.tail<3>().isApprox(u - x.tail<3>()));  // input change from the previous
}

TEST(ProblemExtensionsTest, InputMemoryModelCarriesTheInput) {
  using M = model::InputMemoryModel<model::QuadrotorModel>;
  model::AttitudeModelParams m;
  Vec<M::kNx> x = Vec<M::kNx>::Zero();
  x[2] = 1.0;
  x.tail<3>() = Vec3(1.0, 2.0, 3.0);
  const Vec3 u(14.0, 0.1, -0.05);
  Mat<M::kNx, M::kNx> a = Mat<M::kNx, M::kNx>::Zero();
  Mat<M::kNx, M::kNu> b = Mat<M::kNx, M::kNu>::Zero();
  const Vec<M::kNx> next = M::Discretise(x, u, 0.0, m, 0.05, 2, &a, &b);
  // The memory holds the input; the base state evolves as the base model alone.
  EXPECT_TRUE(next.tail<3>() == u);
  Mat<9, 9> ab = Mat<9, 9>::Zero();
  Mat<9, 3> bb = Mat<9, 3>::Zero();
  const Vec<9> nb =
      model::Discretise<model::QuadrotorModel>(x.head<9>(), u, 0.0, m, 0.05, 2, &ab, &bb);
  EXPECT_TRUE(next.head<9>() == nb);
  EXPECT_TRUE((a.topLeftCorner<9, 9>() == ab));
  EXPECT_TRUE(b.topRows<9>() == bb);
  EXPECT_TRUE(a.rightCols<3>().isZero());
  EXPECT_TRUE(a.bottomRows<3>().isZero());
  EXPECT_TRUE(b.bottomRows<3>().isIdentity());
  // Sensitivities against finite differences of the whole map.
  const double h = 1e-6;
  for (int i = 0; i < M::kNu; ++i) {
    Vec3 up = u, um = u;
    up[i] += h;
    um[i] -= h;
    const Vec<M::kNx> d = (M::Discretise(x, up, 0.0, m, 0.05, 2, nullptr, nullptr) -
                           M::Discretise(x, um, 0.0, m, 0.05, 2, nullptr, nullptr)) /
                          (2 * h);
    EXPECT_LT((d - b.col(i)).cwiseAbs().maxCoeff(), 1e-5) << i;
  }
}

using Accel = WithAcceleration<Full>;

// The interval map of the wrapped problem's model with v' + a, integrated by the generic
// RK4 (rk4.hpp) from the flow: what WithAcceleration's closed form must equal.
Vec<Accel::kNx> GenericRk4WithAcceleration(const Accel& prob, const Vec<Accel::kNx>& x,
                                           const Vec3& u, const Accel::Params& p, double dt,
                                           int steps) {
  using M = Full::Model;
  const auto flow = [&](const Vec<M::kNx>& z, const Vec<3>& v, Vec<M::kNx>* f,
                        Mat<M::kNx, M::kNx>* /*fx*/, Mat<M::kNx, 3>* /*fu*/) {
    // The quadrotor's own flow plus a; the input memory is not a flow (compared apart).
    *f = Vec<M::kNx>::Zero();
    f->template head<9>() =
        model::QuadrotorModel::Flow<double>(z.template head<9>(), v, p[0], prob.base.params);
    f->template segment<3>(model::QuadrotorModel::kVel) +=
        p.template segment<3>(Accel::kParamAcceleration);
  };
  return IntegrateRk4<M::kNx, 3>(flow, x, u, dt, steps);
}

TEST(ProblemExtensionsTest, AccelerationParameterAddsItsExactDoubleIntegral) {
  // Given the follower problem of the controllers wrapped with an acceleration parameter
  std::mt19937 rng(19);
  std::uniform_real_distribution<double> U(-0.3, 0.3);
  const Accel prob(Full(Obst(ReducedFollowerProblem<2>{}, 0.45)));
  static_assert(Accel::kNp == Full::kNp + 3 && Accel::kParamAcceleration == Full::kNp);
  for (int trial = 0; trial < 10; ++trial) {
    Vec<Accel::kNx> x;
    for (int i = 0; i < Accel::kNx; ++i) x[i] = U(rng);
    const Vec3 u(13.0 + U(rng), U(rng), U(rng));
    Accel::Params p;
    for (int i = 0; i < Accel::kNp; ++i) p[i] = 3.0 * U(rng);
    const double dt = 0.05;
    const int steps = 2;
    // When discretised with sensitivities
    Mat<Accel::kNx, Accel::kNx> A = Mat<Accel::kNx, Accel::kNx>::Zero(), A0 = A;
    Mat<Accel::kNx, Accel::kNu> B = Mat<Accel::kNx, Accel::kNu>::Zero(), B0 = B;
    const Vec<Accel::kNx> next = prob.Discretise(x, u, p, dt, steps, &A, &B);
    const Vec<Accel::kNx> plain =
        prob.base.Discretise(x, u, p.head<Full::kNp>(), dt, steps, &A0, &B0);
    // Then the map is the generic RK4 of the flow with v' + a (the closed form is exact)
    EXPECT_LT((next - GenericRk4WithAcceleration(prob, x, u, p, dt, steps))
                  .head<9>()
                  .cwiseAbs()
                  .maxCoeff(),
              1e-12);
    EXPECT_EQ(next.tail<3>(), u);
    // And a shifts p by a dt^2 / 2 and v by a dt, nothing else
    const Vec3 a = p.segment<3>(Accel::kParamAcceleration);
    Vec<Accel::kNx> shift = Vec<Accel::kNx>::Zero();
    shift.segment<3>(0) = 0.5 * dt * dt * a;
    shift.segment<3>(3) = dt * a;
    EXPECT_LT((next - plain - shift).cwiseAbs().maxCoeff(), 1e-14);
    // And the sensitivities are the wrapped ones, which match central differences
    EXPECT_EQ(A, A0);
    EXPECT_EQ(B, B0);
    using ::fnmpc::testing::NumericJacobian;
    const auto map_x = [&](const Vec<Accel::kNx>& z) {
      return prob.Discretise(z, u, p, dt, steps, nullptr, nullptr);
    };
    const auto map_u = [&](const Vec<Accel::kNu>& v) {
      return prob.Discretise(x, v, p, dt, steps, nullptr, nullptr);
    };
    EXPECT_LT((NumericJacobian<Accel::kNx>(x, map_x) - A).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_LT((NumericJacobian<Accel::kNu>(u, map_u) - B).cwiseAbs().maxCoeff(), 1e-6);
    // And the residuals and their Jacobians are the wrapped problem's
    CheckJacobians(prob, x, u, p);
    Vec<Accel::kNy> y;
    Vec<Full::kNy> yb;
    prob.StageResidual(x, u, p, &y, nullptr, nullptr);
    prob.base.StageResidual(x, u, p.head<Full::kNp>(), &yb, nullptr, nullptr);
    EXPECT_EQ(y, yb);
  }
  // And with a = 0 the map is the wrapped problem's to the bit
  Vec<Accel::kNx> x = Vec<Accel::kNx>::Constant(0.1);
  Accel::Params p = Accel::Params::Zero();
  p[0] = 0.2;
  EXPECT_EQ(prob.Discretise(x, Vec3(13.0, 0.05, -0.02), p, 0.05, 2, nullptr, nullptr),
            prob.base.Discretise(x, Vec3(13.0, 0.05, -0.02), p.head<Full::kNp>(), 0.05, 2, nullptr,
                                 nullptr));
}

}  // namespace
}  // namespace fnmpc::ocp

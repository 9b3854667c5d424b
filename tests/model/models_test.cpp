// SPDX-License-Identifier: BSD-3-Clause
// Derivatives of every model, integrator and residual against central finite differences.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "fnmpc/model/follower_model.hpp"
#include "fnmpc/model/quadrotor_model.hpp"
#include "fnmpc/model/rk4.hpp"
#include "fnmpc/ocp/problems.hpp"

namespace fnmpc {
namespace {

template <int N>
Vec<N> RandomVec(std::mt19937* rng, double scale) {
  std::uniform_real_distribution<double> d(-scale, scale);
  Vec<N> v;
  for (int i = 0; i < N; ++i) v[i] = d(*rng);
  return v;
}

template <class Model>
void CheckModelJacobians(std::mt19937* rng) {
  const model::AttitudeModelParams m;
  for (int trial = 0; trial < 10; ++trial) {
    // Given a random state and input around hover
    const Vec<Model::kNx> x = RandomVec<Model::kNx>(rng, 0.6);
    Vec<3> u = RandomVec<3>(rng, 0.3);
    u[0] += m.mass * kGravity;
    const double psi_ref = 0.2;
    // When the hand-derived Jacobians are evaluated
    Vec<Model::kNx> f;
    Mat<Model::kNx, Model::kNx> fx;
    Mat<Model::kNx, 3> fu;
    Model::FlowJacobian(x, u, psi_ref, m, &f, &fx, &fu);
    // Then they match the flow and central differences
    EXPECT_LT((f - Model::template Flow<double>(x, u, psi_ref, m)).norm(), 1e-12);
    const double h = 1e-6;
    for (int i = 0; i < Model::kNx; ++i) {
      Vec<Model::kNx> xp = x, xm = x;
      xp[i] += h;
      xm[i] -= h;
      const Vec<Model::kNx> col = (Model::template Flow<double>(xp, u, psi_ref, m) -
                                   Model::template Flow<double>(xm, u, psi_ref, m)) /
                                  (2 * h);
      EXPECT_LT((col - fx.col(i)).norm(), 1e-7) << "state " << i;
    }
    for (int i = 0; i < 3; ++i) {
      Vec<3> up = u, um = u;
      up[i] += h;
      um[i] -= h;
      const Vec<Model::kNx> col = (Model::template Flow<double>(x, up, psi_ref, m) -
                                   Model::template Flow<double>(x, um, psi_ref, m)) /
                                  (2 * h);
      EXPECT_LT((col - fu.col(i)).norm(), 1e-7) << "input " << i;
    }
  }
}

TEST(ModelTest, QuadrotorJacobiansMatchFiniteDifferences) {
  std::mt19937 rng(1);
  CheckModelJacobians<model::QuadrotorModel>(&rng);
}

TEST(ModelTest, FollowerJacobiansMatchFiniteDifferences) {
  std::mt19937 rng(2);
  CheckModelJacobians<model::FollowerModel<2>>(&rng);
  CheckModelJacobians<model::FollowerModel<6>>(&rng);
}

TEST(ModelTest, HoverIsAnEquilibrium) {
  // Given level attitude and thrust m g
  const model::AttitudeModelParams m;
  Vec<9> x = Vec<9>::Zero();
  const Vec3 u(m.mass * kGravity, 0, 0);
  // Then nothing moves
  EXPECT_LT(model::QuadrotorModel::Flow<double>(x, u, 0.0, m).norm(), 1e-12);
}

template <class Model>
void CheckRk4Sensitivities(std::mt19937* rng, int steps) {
  const model::AttitudeModelParams m;
  const Vec<Model::kNx> x = RandomVec<Model::kNx>(rng, 0.5);
  Vec<3> u = RandomVec<3>(rng, 0.3);
  u[0] += 12.0;
  Mat<Model::kNx, Model::kNx> A;
  Mat<Model::kNx, 3> B;
  const Vec<Model::kNx> xn = model::Rk4<Model>(x, u, 0.1, m, 0.05, steps, &A, &B);
  EXPECT_LT((xn - model::Rk4<Model>(x, u, 0.1, m, 0.05, steps)).norm(), 1e-14);
  const double h = 1e-6;
  for (int i = 0; i < Model::kNx; ++i) {
    Vec<Model::kNx> xp = x, xm = x;
    xp[i] += h;
    xm[i] -= h;
    const Vec<Model::kNx> col = (model::Rk4<Model>(xp, u, 0.1, m, 0.05, steps) -
                                 model::Rk4<Model>(xm, u, 0.1, m, 0.05, steps)) /
                                (2 * h);
    EXPECT_LT((col - A.col(i)).norm(), 1e-8) << "state " << i;
  }
  for (int i = 0; i < 3; ++i) {
    Vec<3> up = u, um = u;
    up[i] += h;
    um[i] -= h;
    const Vec<Model::kNx> col = (model::Rk4<Model>(x, up, 0.1, m, 0.05, steps) -
                                 model::Rk4<Model>(x, um, 0.1, m, 0.05, steps)) /
                                (2 * h);
    EXPECT_LT((col - B.col(i)).norm(), 1e-8) << "input " << i;
  }
}

TEST(Rk4Test, SensitivitiesMatchFiniteDifferences) {
  std::mt19937 rng(3);
  for (int steps : {1, 2, 4}) {
    CheckRk4Sensitivities<model::QuadrotorModel>(&rng, steps);
    CheckRk4Sensitivities<model::FollowerModel<2>>(&rng, steps);
  }
}

// The structured Discretise must be the generic Rk4's map and derivative, and every entry
// it leaves unwritten (its structural zeros) must be exactly zero in the generic result.
template <class Model>
void CheckStructuredDiscretisation(std::mt19937* rng, int steps) {
  static_assert(model::HasStructuredDiscretisation<Model>::value,
                "model::Discretise must pick the structured map of this model");
  constexpr int nx = Model::kNx;
  const model::AttitudeModelParams m;
  for (int trial = 0; trial < 6; ++trial) {
    const Vec<nx> x = RandomVec<nx>(rng, 0.6);
    Vec<3> u = RandomVec<3>(rng, 0.35);
    u[0] += 13.0;
    // (the last trial is a yaw step of about 3 rad: a fast yaw inside the interval)
    const double psi_ref = trial < 5 ? 0.3 * trial - 0.5 : 3.0;
    Mat<nx, nx> a_ref;
    Mat<nx, 3> b_ref;
    const Vec<nx> x_ref = model::Rk4<Model>(x, u, psi_ref, m, 0.05, steps, &a_ref, &b_ref);
    Mat<nx, nx> a = Mat<nx, nx>::Constant(kNaN);
    Mat<nx, 3> b = Mat<nx, 3>::Constant(kNaN);
    const Vec<nx> xn = Model::Discretise(x, u, psi_ref, m, 0.05, steps, &a, &b);
    EXPECT_LT((xn - x_ref).cwiseAbs().maxCoeff(), 1e-12);
    for (int i = 0; i < nx; ++i) {
      for (int j = 0; j < nx; ++j) {
        if (std::isnan(a(i, j))) {
          EXPECT_EQ(a_ref(i, j), 0.0) << "A(" << i << "," << j << ") is not a structural zero";
        } else {
          EXPECT_NEAR(a(i, j), a_ref(i, j), 1e-12) << "A(" << i << "," << j << ")";
        }
      }
      for (int j = 0; j < 3; ++j) {
        if (std::isnan(b(i, j))) {
          EXPECT_EQ(b_ref(i, j), 0.0) << "B(" << i << "," << j << ") is not a structural zero";
        } else {
          EXPECT_NEAR(b(i, j), b_ref(i, j), 1e-12) << "B(" << i << "," << j << ")";
        }
      }
    }
    // Without sensitivities the same next state.
    EXPECT_EQ(Model::Discretise(x, u, psi_ref, m, 0.05, steps, nullptr, nullptr), xn);
  }
}

TEST(Rk4Test, StructuredDiscretisationEqualsGenericRk4) {
  std::mt19937 rng(11);
  for (int steps : {1, 2, 3}) {
    CheckStructuredDiscretisation<model::QuadrotorModel>(&rng, steps);
    CheckStructuredDiscretisation<model::FollowerModel<2>>(&rng, steps);
    CheckStructuredDiscretisation<model::FollowerModel<6>>(&rng, steps);
  }
}

TEST(Rk4Test, StructuredTransitionProductsEqualDenseProducts) {
  std::mt19937 rng(5);
  const model::AttitudeModelParams m;
  for (int trial = 0; trial < 5; ++trial) {
    // Given: a transition matrix of Discretise (zero off its structure) at a random point
    const Vec<9> x = RandomVec<9>(&rng, 0.6);
    Vec<3> u = RandomVec<3>(&rng, 0.35);
    u[0] += 13.0;
    Mat<9, 9> a = Mat<9, 9>::Zero();
    Mat<9, 3> b = Mat<9, 3>::Zero();
    model::QuadrotorModel::Discretise(x, u, 0.2, m, 0.05, 2, &a, &b);
    Mat<9, 3> in = Mat<9, 3>::Zero();
    Mat<4, 9> in_left = Mat<4, 9>::Zero();
    for (int i = 0; i < 9; ++i) {
      in.row(i) = RandomVec<3>(&rng, 1.0).transpose();
      in_left.col(i) = RandomVec<4>(&rng, 1.0);
    }
    // When: multiplied by the structured products
    Mat<9, 3> out;
    Mat<4, 9> out_left;
    model::QuadrotorModel::MultiplyTransition(a, in, &out);
    model::QuadrotorModel::MultiplyTransitionRight(in_left, a, &out_left);
    Mat<9, 3> out_transposed;
    model::QuadrotorModel::MultiplyTransitionTransposed(a, in, &out_transposed);
    EXPECT_LT((out_transposed - a.transpose() * in).cwiseAbs().maxCoeff(), 1e-14);
    // Then: the dense products
    EXPECT_LT((out - a * in).cwiseAbs().maxCoeff(), 1e-14);
    EXPECT_LT((out_left - in_left * a).cwiseAbs().maxCoeff(), 1e-14);
  }
}

TEST(Rk4Test, FourthOrderConvergence) {
  // Given a tilted vehicle, the RK4 error shrinks ~16x when the step halves
  const model::AttitudeModelParams m;
  Vec<9> x = Vec<9>::Zero();
  x[6] = 0.3;
  x[7] = -0.2;
  const Vec3 u(15.0, -0.2, 0.25);
  const Vec<9> ref = model::Rk4<model::QuadrotorModel>(x, u, 0.4, m, 0.5, 512);
  const double e1 = (model::Rk4<model::QuadrotorModel>(x, u, 0.4, m, 0.5, 16) - ref).norm();
  const double e2 = (model::Rk4<model::QuadrotorModel>(x, u, 0.4, m, 0.5, 32) - ref).norm();
  EXPECT_GT(e1 / e2, 12.0);
  EXPECT_LT(e1 / e2, 20.0);
}

template <class Problem>
void CheckResidualJacobians(const Problem& prob, std::mt19937* rng) {
  constexpr int nx = Problem::kNx, ny = Problem::kNy, nyn = Problem::kNyN, np = Problem::kNp;
  const Vec<nx> x = RandomVec<nx>(rng, 1.0);
  Vec<3> u = RandomVec<3>(rng, 0.3);
  const Vec<np> p = RandomVec<np>(rng, 2.0);
  // The problems write only the structural nonzeros of the Jacobians; the finite
  // differences below check every entry, so an unwritten entry must be a true zero.
  Vec<ny> y;
  Mat<ny, nx> yx = Mat<ny, nx>::Zero();
  Mat<ny, 3> yu = Mat<ny, 3>::Zero();
  prob.StageResidual(x, u, p, &y, &yx, &yu);
  Vec<nyn> yn;
  Mat<nyn, nx> ynx = Mat<nyn, nx>::Zero();
  prob.TerminalResidual(x, p, &yn, &ynx);
  const double h = 1e-6;
  for (int i = 0; i < nx; ++i) {
    Vec<nx> xp = x, xm = x;
    xp[i] += h;
    xm[i] -= h;
    Vec<ny> yp, ym;
    Vec<nyn> ynp, ynm;
    prob.StageResidual(xp, u, p, &yp, nullptr, nullptr);
    prob.StageResidual(xm, u, p, &ym, nullptr, nullptr);
    prob.TerminalResidual(xp, p, &ynp, nullptr);
    prob.TerminalResidual(xm, p, &ynm, nullptr);
    EXPECT_LT(((yp - ym) / (2 * h) - yx.col(i)).norm(), 1e-7) << "state " << i;
    EXPECT_LT(((ynp - ynm) / (2 * h) - ynx.col(i)).norm(), 1e-7) << "state " << i;
  }
  for (int i = 0; i < 3; ++i) {
    Vec<3> up = u, um = u;
    up[i] += h;
    um[i] -= h;
    Vec<ny> yp, ym;
    prob.StageResidual(x, up, p, &yp, nullptr, nullptr);
    prob.StageResidual(x, um, p, &ym, nullptr, nullptr);
    EXPECT_LT(((yp - ym) / (2 * h) - yu.col(i)).norm(), 1e-7) << "input " << i;
  }
}

TEST(ResidualTest, AllProblemsMatchFiniteDifferences) {
  std::mt19937 rng(4);
  CheckResidualJacobians(ocp::LeaderProblem{}, &rng);
  for (auto frame : {ocp::TargetFrame::kInertial, ocp::TargetFrame::kControl}) {
    CheckResidualJacobians(ocp::FollowerProblem<2>{{}, frame}, &rng);
    CheckResidualJacobians(ocp::FollowerProblem<6>{{}, frame}, &rng);
    CheckResidualJacobians(ocp::ReducedFollowerProblem<2>{{}, frame}, &rng);
    CheckResidualJacobians(ocp::ReducedFollowerProblem<6>{{}, frame}, &rng);
  }
}

TEST(ResidualTest, ControlFrameRotatesByOwnYaw) {
  // Given a follower yawed by 90 degrees with a neighbour 1 m north (+y) in {m}
  ocp::FollowerProblem<2> prob{{}, ocp::TargetFrame::kControl};
  Vec<22> x = Vec<22>::Zero();
  x[5] = M_PI / 2;
  x.segment<3>(6) = Vec3(0, 1, 0);
  Vec<17> y;
  prob.StageResidual(x, Vec3(13.4, 0, 0), Vec<1>::Zero(), &y, nullptr, nullptr);
  // Then in its control frame the neighbour is straight ahead (+x)
  EXPECT_NEAR(y[0], 1.0, 1e-12);
  EXPECT_NEAR(y[1], 0.0, 1e-12);
}

}  // namespace
}  // namespace fnmpc

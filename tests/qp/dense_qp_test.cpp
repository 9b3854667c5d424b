// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/qp/dense_qp.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/QR>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "tests/qp/qp_test_problems.hpp"

namespace fnmpc::qp {
namespace {

using testing::CheckKkt;
using testing::Gaussian;
using testing::kInfBound;
using testing::RandomFeasibleQp;
using testing::RandomQpOptions;
using testing::RandomSpd;

constexpr double kKktTol = 1e-8;
constexpr double kNaNValue = std::numeric_limits<double>::quiet_NaN();

double Objective(const DenseQp& qp, const Eigen::VectorXd& x) {
  return 0.5 * x.dot(qp.H * x) + qp.g.dot(x);
}

// ---------------------------------------------------------------------------------------
// Random feasible QPs, parametrised over (nv, nc, equality share).

class RandomQpTest : public ::testing::TestWithParam<std::tuple<int, int, double>> {};

TEST_P(RandomQpTest, SolvesToKktTolerance) {
  const auto [nv, nc, eq_share] = GetParam();
  std::mt19937 rng(1234 + 17 * nv + nc);
  const int kTrials = nv * nc > 5000 ? 6 : 15;
  int total_active = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    // Given: a random strictly convex QP with a known feasible point
    RandomQpOptions opt;
    opt.equality_share = eq_share;
    Eigen::VectorXd x_feasible;
    const DenseQp qp = RandomFeasibleQp(nv, nc, &rng, opt, &x_feasible);
    DenseQpSolver solver(qp.dims());
    QpSolution sol(qp.dims());

    // When: solved cold
    const QpStatus status = solver.Solve(qp, &sol);

    // Then: optimal, KKT holds (recomputed here), the objective beats the feasible point
    ASSERT_EQ(status, QpStatus::kOptimal) << "trial " << trial;
    EXPECT_EQ(sol.status, QpStatus::kOptimal);
    ASSERT_TRUE(sol.x.allFinite());
    const auto kkt = CheckKkt(qp, sol);
    EXPECT_LE(kkt.stationarity, kKktTol) << "trial " << trial;
    EXPECT_LE(kkt.primal, kKktTol) << "trial " << trial;
    EXPECT_LE(kkt.dual, kKktTol) << "trial " << trial;
    EXPECT_LE(kkt.complementarity, kKktTol) << "trial " << trial;
    EXPECT_LE(ComputeKktResiduals(qp, sol).Max(), kKktTol);
    EXPECT_LE(sol.objective, Objective(qp, x_feasible) + 1e-9);
    EXPECT_NEAR(sol.objective, Objective(qp, sol.x), 1e-9 * (1.0 + std::abs(sol.objective)));
    EXPECT_GE(sol.iterations, sol.num_active);
    total_active += sol.num_active;
  }
  // The family must exercise the active-set machinery.
  EXPECT_GT(total_active, kTrials);
}

INSTANTIATE_TEST_SUITE_P(
    Sizes, RandomQpTest,
    ::testing::Values(std::make_tuple(3, 0, 0.0), std::make_tuple(5, 8, 0.0),
                      std::make_tuple(12, 30, 0.1), std::make_tuple(30, 60, 0.0),
                      std::make_tuple(45, 45, 0.0), std::make_tuple(45, 135, 0.0),
                      std::make_tuple(45, 135, 0.05), std::make_tuple(60, 315, 0.0)));

// ---------------------------------------------------------------------------------------

TEST(DenseQpSolverTest, MatchesUnconstrainedSolutionWhenNothingIsActive) {
  // Given: constraints placed around the unconstrained minimiser, none of them active
  std::mt19937 rng(7);
  const int nv = 20;
  const int nc = 10;
  DenseQp qp(DenseQpDims{nv, nc});
  qp.H = RandomSpd(nv, 0.5, &rng);
  qp.g = Gaussian(nv, 1, &rng);
  const Eigen::VectorXd x_free = qp.H.ldlt().solve(-qp.g);
  qp.lb = x_free.array() - 1.0;
  qp.ub = x_free.array() + 1.0;
  qp.A = Gaussian(nc, nv, &rng);
  qp.lbA = (qp.A * x_free).array() - 1.0;
  qp.ubA = (qp.A * x_free).array() + 1.0;
  DenseQpSolver solver(qp.dims());
  QpSolution sol(qp.dims());

  // When
  ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);

  // Then: the unconstrained solution, zero multipliers, no active-set change
  EXPECT_LE((sol.x - x_free).lpNorm<Eigen::Infinity>(), 1e-10);
  EXPECT_EQ(sol.y_bounds.lpNorm<Eigen::Infinity>(), 0.0);
  EXPECT_EQ(sol.y_constraints.lpNorm<Eigen::Infinity>(), 0.0);
  EXPECT_EQ(sol.iterations, 0);
  EXPECT_EQ(sol.num_active, 0);
}

TEST(DenseQpSolverTest, EqualityConstrainedQpMatchesKktSystem) {
  // Given: 3 general equalities and 2 fixed variables, all inequalities absent
  std::mt19937 rng(11);
  const int nv = 10;
  const int nc = 3;
  DenseQp qp(DenseQpDims{nv, nc});
  qp.H = RandomSpd(nv, 0.2, &rng);
  qp.g = Gaussian(nv, 1, &rng);
  qp.A = Gaussian(nc, nv, &rng);
  qp.lbA = Gaussian(nc, 1, &rng);
  qp.ubA = qp.lbA;
  qp.lb[2] = qp.ub[2] = 0.5;
  qp.lb[7] = qp.ub[7] = -0.25;
  // Reference: [H E'; E 0] [x; lambda] = [-g; b]
  Eigen::MatrixXd e = Eigen::MatrixXd::Zero(nc + 2, nv);
  Eigen::VectorXd b(nc + 2);
  e.topRows(nc) = qp.A;
  b.head(nc) = qp.lbA;
  e(nc, 2) = 1.0;
  b[nc] = 0.5;
  e(nc + 1, 7) = 1.0;
  b[nc + 1] = -0.25;
  Eigen::MatrixXd kkt = Eigen::MatrixXd::Zero(nv + nc + 2, nv + nc + 2);
  kkt.topLeftCorner(nv, nv) = qp.H;
  kkt.topRightCorner(nv, nc + 2) = e.transpose();
  kkt.bottomLeftCorner(nc + 2, nv) = e;
  Eigen::VectorXd rhs(nv + nc + 2);
  rhs << -qp.g, b;
  const Eigen::VectorXd ref = kkt.partialPivLu().solve(rhs);
  DenseQpSolver solver(qp.dims());
  QpSolution sol(qp.dims());

  // When
  ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);

  // Then
  EXPECT_LE((sol.x - ref.head(nv)).lpNorm<Eigen::Infinity>(), 1e-9);
  EXPECT_LE((qp.A * sol.x - qp.lbA).lpNorm<Eigen::Infinity>(), 1e-10);
  EXPECT_NEAR(sol.x[2], 0.5, 1e-12);
  EXPECT_NEAR(sol.x[7], -0.25, 1e-12);
  EXPECT_LE(CheckKkt(qp, sol).Max(), kKktTol);
  EXPECT_EQ(sol.num_active, nc + 2);
}

TEST(DenseQpSolverTest, EqualitiesMixedWithActiveInequalities) {
  // Given: random QPs with a third of the rows as equalities and a strong pull outwards
  std::mt19937 rng(12);
  RandomQpOptions opt;
  opt.equality_share = 0.3;
  opt.g_scale = 30.0;
  for (int trial = 0; trial < 10; ++trial) {
    const DenseQp qp = RandomFeasibleQp(20, 12, &rng, opt);
    DenseQpSolver solver(qp.dims());
    QpSolution sol(qp.dims());
    // When
    ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
    // Then: equalities hold and KKT is satisfied
    for (int i = 0; i < 12; ++i) {
      if (qp.lbA[i] == qp.ubA[i]) {
        EXPECT_NEAR(qp.A.row(i).dot(sol.x), qp.lbA[i], 1e-9);
      }
    }
    EXPECT_LE(CheckKkt(qp, sol).Max(), kKktTol);
  }
}

TEST(DenseQpSolverTest, DuplicatedAndScaledRowsAreDegenerateButSolved) {
  std::mt19937 rng(21);
  for (int trial = 0; trial < 10; ++trial) {
    // Given: a random QP whose rows are repeated exactly and as scaled copies
    const DenseQp base = RandomFeasibleQp(15, 10, &rng);
    DenseQp qp(DenseQpDims{15, 30});
    qp.H = base.H;
    qp.g = base.g;
    qp.lb = base.lb;
    qp.ub = base.ub;
    qp.A << base.A, base.A, 3.0 * base.A;
    qp.lbA << base.lbA, base.lbA, 3.0 * base.lbA;
    qp.ubA << base.ubA, base.ubA, 3.0 * base.ubA;
    DenseQpSolver solver(qp.dims());
    QpSolution sol(qp.dims());
    DenseQpSolver base_solver(base.dims());
    QpSolution base_sol(base.dims());
    // When
    ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
    ASSERT_EQ(base_solver.Solve(base, &base_sol), QpStatus::kOptimal);
    // Then: same minimiser as without duplicates, KKT holds
    EXPECT_LE((sol.x - base_sol.x).lpNorm<Eigen::Infinity>(), 1e-8);
    EXPECT_LE(CheckKkt(qp, sol).Max(), kKktTol);
  }
}

TEST(DenseQpSolverTest, RedundantConstraintsActiveAtTheOptimum) {
  // Given: 2 nv constraints all tight at x_star, g chosen so that x_star is optimal with
  // positive multipliers on a few of them (more active rows than variables)
  std::mt19937 rng(31);
  const int nv = 10;
  const int nc = 2 * nv;
  for (int trial = 0; trial < 10; ++trial) {
    DenseQp qp(DenseQpDims{nv, nc});
    qp.H = RandomSpd(nv, 0.3, &rng);
    const Eigen::VectorXd x_star = Gaussian(nv, 1, &rng);
    qp.A = Gaussian(nc, nv, &rng);
    qp.ubA = qp.A * x_star;
    Eigen::VectorXd y = Eigen::VectorXd::Zero(nc);
    for (int i = 0; i < 4; ++i) y[i] = testing::Uniform(0.5, 2.0, &rng);
    qp.g = -qp.H * x_star - qp.A.transpose() * y;
    // ... plus two bounds tight at x_star as well
    qp.ub[0] = x_star[0];
    qp.lb[1] = x_star[1];
    DenseQpSolver solver(qp.dims());
    QpSolution sol(qp.dims());
    // When
    ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal) << "trial " << trial;
    // Then
    EXPECT_LE((sol.x - x_star).lpNorm<Eigen::Infinity>(), 1e-8);
    EXPECT_LE(CheckKkt(qp, sol).Max(), kKktTol);
  }
}

TEST(DenseQpSolverTest, RedundantEqualityRowsAreSkipped) {
  // Given: x0 + x1 = 1 written twice (once scaled) and minimise |x - (2, 2)|^2
  DenseQp qp(DenseQpDims{2, 2});
  qp.H = Eigen::Matrix2d::Identity();
  qp.g << -2.0, -2.0;
  qp.A << 1.0, 1.0, 2.0, 2.0;
  qp.lbA << 1.0, 2.0;
  qp.ubA = qp.lbA;
  DenseQpSolver solver(qp.dims());
  QpSolution sol(qp.dims());
  // When
  ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
  // Then
  EXPECT_NEAR(sol.x[0], 0.5, 1e-12);
  EXPECT_NEAR(sol.x[1], 0.5, 1e-12);
  EXPECT_LE(CheckKkt(qp, sol).Max(), kKktTol);
}

TEST(DenseQpSolverTest, IllConditionedHessian) {
  // Given: H = V diag(lambda) V' with lambda log-uniform in [1e-6, 1e2] (condition ~1e8)
  std::mt19937 rng(33);
  const int nv = 30;
  const int nc = 60;
  for (int trial = 0; trial < 10; ++trial) {
    DenseQp qp = RandomFeasibleQp(nv, nc, &rng);
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Gaussian(nv, nv, &rng));
    const Eigen::MatrixXd v = qr.householderQ();
    Eigen::VectorXd lambda(nv);
    for (int i = 0; i < nv; ++i) lambda[i] = std::pow(10.0, testing::Uniform(-6.0, 2.0, &rng));
    qp.H = v * lambda.asDiagonal() * v.transpose();
    qp.H = 0.5 * (qp.H + qp.H.transpose()).eval();
    DenseQpSolver solver(qp.dims());
    QpSolution sol(qp.dims());
    // When
    ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal) << "trial " << trial;
    // Then: KKT holds; stationarity relative to the size of its terms
    const auto kkt = CheckKkt(qp, sol);
    const double scale = 1.0 + qp.g.lpNorm<Eigen::Infinity>() +
                         qp.H.lpNorm<Eigen::Infinity>() * sol.x.lpNorm<Eigen::Infinity>();
    EXPECT_LE(kkt.stationarity / scale, kKktTol) << "trial " << trial;
    EXPECT_LE(kkt.primal, kKktTol) << "trial " << trial;
    EXPECT_LE(kkt.dual, kKktTol) << "trial " << trial;
    EXPECT_LE(kkt.complementarity / scale, kKktTol) << "trial " << trial;
  }
}

TEST(DenseQpSolverTest, LowRankConstraintsWithRedundantEqualities) {
  // Given: A of rank nv/3 (many linearly dependent rows), a fifth of them equalities,
  // all consistent (x = 0 is feasible)
  std::mt19937 rng(35);
  const int nv = 45;
  const int nc = 135;
  for (int trial = 0; trial < 10; ++trial) {
    DenseQp qp(DenseQpDims{nv, nc});
    qp.H = RandomSpd(nv, 0.1, &rng);
    qp.g = 10.0 * Gaussian(nv, 1, &rng);
    qp.A = Gaussian(nc, nv / 3, &rng) * Gaussian(nv / 3, nv, &rng);
    for (int i = 0; i < nc; ++i) {
      if (testing::Uniform(0.0, 1.0, &rng) < 0.2) {
        qp.lbA[i] = qp.ubA[i] = 0.0;
      } else {
        qp.lbA[i] = -testing::Uniform(0.0, 1.0, &rng);
        qp.ubA[i] = testing::Uniform(0.0, 1.0, &rng);
      }
    }
    for (int j = 0; j < nv; ++j) {
      qp.lb[j] = -testing::Uniform(0.0, 1.0, &rng);
      qp.ub[j] = testing::Uniform(0.0, 1.0, &rng);
    }
    DenseQpSolver solver(qp.dims());
    QpSolution sol(qp.dims());
    // When
    ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal) << "trial " << trial;
    // Then
    EXPECT_LE(CheckKkt(qp, sol).Max(), kKktTol) << "trial " << trial;
    EXPECT_LE(sol.objective, 1e-9);  // x = 0 is feasible with objective 0
  }
}

// ---------------------------------------------------------------------------------------
// Infeasible problems.

void ExpectInfeasible(const DenseQp& qp) {
  DenseQpSolver solver(qp.dims());
  QpSolution sol(qp.dims());
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kInfeasible);
  EXPECT_EQ(sol.status, QpStatus::kInfeasible);
  EXPECT_TRUE(sol.x.allFinite());
  EXPECT_TRUE(sol.y_bounds.allFinite());
  EXPECT_TRUE(sol.y_constraints.allFinite());
}

TEST(DenseQpSolverTest, InfeasibleBoundAgainstRow) {
  // Given: x0 >= 1 as a bound and x0 <= 0 as a general row
  DenseQp qp(DenseQpDims{3, 1});
  qp.H = Eigen::Matrix3d::Identity();
  qp.g << 0.1, 0.2, 0.3;
  qp.lb[0] = 1.0;
  qp.A << 1.0, 0.0, 0.0;
  qp.ubA[0] = 0.0;
  // Then
  ExpectInfeasible(qp);
}

TEST(DenseQpSolverTest, InfeasibleImpliedCombination) {
  // Given: x0 + x1 >= 3 with x0 <= 1 and x1 <= 1
  DenseQp qp(DenseQpDims{2, 1});
  qp.H = Eigen::Matrix2d::Identity();
  qp.g << 1.0, -1.0;
  qp.ub << 1.0, 1.0;
  qp.A << 1.0, 1.0;
  qp.lbA[0] = 3.0;
  ExpectInfeasible(qp);
}

TEST(DenseQpSolverTest, InfeasibleRowsWithCrossedSides) {
  // Given: a' x <= 1 and a' x >= 2 on two different rows of a random 8-variable QP
  std::mt19937 rng(41);
  DenseQp qp(DenseQpDims{8, 2});
  qp.H = RandomSpd(8, 0.5, &rng);
  qp.g = Gaussian(8, 1, &rng);
  qp.A.row(0) = Gaussian(1, 8, &rng);
  qp.A.row(1) = qp.A.row(0);
  qp.ubA[0] = 1.0;
  qp.lbA[1] = 2.0;
  ExpectInfeasible(qp);
}

TEST(DenseQpSolverTest, InfeasibleConflictingEqualities) {
  // Given: x0 + x1 = 1 and x0 + x1 = 2
  DenseQp qp(DenseQpDims{2, 2});
  qp.H = Eigen::Matrix2d::Identity();
  qp.A << 1.0, 1.0, 1.0, 1.0;
  qp.lbA << 1.0, 2.0;
  qp.ubA = qp.lbA;
  ExpectInfeasible(qp);
}

TEST(DenseQpSolverTest, InfeasibleRandomQpThenRecovers) {
  // Given: a feasible random QP plus a row pair that excludes every point
  std::mt19937 rng(43);
  const DenseQp base = RandomFeasibleQp(30, 40, &rng);
  DenseQp qp = base;
  qp.A.row(5) = qp.A.row(9);
  qp.lbA[5] = qp.ubA[9] + 0.5;
  qp.ubA[5] = kInfBound;
  DenseQpSolver solver(qp.dims());
  QpSolution sol(qp.dims());
  // When / Then: infeasible first, then the same solver solves the feasible problem
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kInfeasible);
  EXPECT_TRUE(sol.x.allFinite());
  ASSERT_EQ(solver.Solve(base, &sol), QpStatus::kOptimal);
  EXPECT_LE(CheckKkt(base, sol).Max(), kKktTol);
}

TEST(DenseQpSolverTest, RandomInfeasibleFamilies) {
  // Given: feasible random QPs made infeasible by a row that contradicts another one by
  // 1e-4..1 (scaled copy) or by a sum row above the sum of the upper bounds
  std::mt19937 rng(47);
  int checked = 0;
  for (int trial = 0; trial < 40; ++trial) {
    RandomQpOptions opt;
    opt.one_sided_share = 0.0;
    DenseQp qp = RandomFeasibleQp(20, 30, &rng, opt);
    const double gap = std::pow(10.0, testing::Uniform(-4.0, 0.0, &rng));
    if (trial % 2 == 0) {
      const double scale = testing::Uniform(0.5, 2.0, &rng);
      qp.A.row(7) = scale * qp.A.row(3);
      qp.lbA[7] = scale * qp.ubA[3] + gap;
      qp.ubA[7] = kInfBound;
    } else {
      qp.A.row(0).setOnes();
      qp.lbA[0] = qp.ub.sum() + gap;
      qp.ubA[0] = kInfBound;
    }
    // When / Then
    ExpectInfeasible(qp);
    ++checked;
  }
  EXPECT_EQ(checked, 40);
}

// ---------------------------------------------------------------------------------------
// Invalid data.

TEST(DenseQpSolverTest, CrossedBoundsAreInvalidInput) {
  // Given: lb > ub on one variable, then lbA > ubA on one row
  std::mt19937 rng(51);
  DenseQp qp = RandomFeasibleQp(6, 4, &rng);
  DenseQpSolver solver(qp.dims());
  QpSolution sol(qp.dims());
  qp.lb[3] = 1.0;
  qp.ub[3] = 0.0;
  // Then
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kInvalidInput);
  qp.lb[3] = -1.0;
  qp.lbA[2] = 2.0;
  qp.ubA[2] = 1.0;
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kInvalidInput);
  EXPECT_TRUE(sol.x.allFinite());
}

TEST(DenseQpSolverTest, WrongSizesAreInvalidInput) {
  DenseQpSolver solver(DenseQpDims{4, 2});
  QpSolution sol(DenseQpDims{4, 2});
  DenseQp qp(DenseQpDims{5, 2});
  qp.H.setIdentity();
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kInvalidInput);
  DenseQp ok(DenseQpDims{4, 2});
  ok.H.setIdentity();
  EXPECT_EQ(solver.Solve(ok, nullptr), QpStatus::kInvalidInput);
  // A solution of the wrong size is resized rather than rejected.
  QpSolution unsized;
  EXPECT_EQ(solver.Solve(ok, &unsized), QpStatus::kOptimal);
  EXPECT_EQ(unsized.x.size(), 4);
}

TEST(DenseQpSolverTest, NonFiniteDataIsNumericalError) {
  std::mt19937 rng(61);
  const DenseQp base = RandomFeasibleQp(6, 4, &rng);
  DenseQpSolver solver(base.dims());
  QpSolution sol(base.dims());
  // Given / When / Then: NaN in g
  DenseQp qp = base;
  qp.g[1] = kNaNValue;
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNumericalError);
  EXPECT_TRUE(sol.x.allFinite());
  // Inf in H
  qp = base;
  qp.H(2, 2) = kInfBound;
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNumericalError);
  // NaN in A
  qp = base;
  qp.A(3, 0) = kNaNValue;
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNumericalError);
  // Infinite bounds are fine
  qp = base;
  qp.lb.setConstant(-kInfBound);
  qp.ubA.setConstant(kInfBound);
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
}

TEST(DenseQpSolverTest, IndefiniteOrSingularHessianIsNotConvex) {
  DenseQpSolver solver(DenseQpDims{3, 0});
  QpSolution sol(DenseQpDims{3, 0});
  DenseQp qp(DenseQpDims{3, 0});
  // Given: indefinite
  qp.H = Eigen::Vector3d(1.0, -1.0, 2.0).asDiagonal();
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNotConvex);
  // Given: positive semidefinite (rank 2)
  qp.H = Eigen::Vector3d(1.0, 0.0, 2.0).asDiagonal();
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNotConvex);
  // Given: numerically singular (pivot 1e-20 against 1)
  qp.H = Eigen::Vector3d(1.0, 1e-20, 2.0).asDiagonal();
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNotConvex);
  EXPECT_TRUE(sol.x.allFinite());
  // Given: positive definite again -> the solver is not stuck in a failed state
  qp.H = Eigen::Vector3d(1.0, 3.0, 2.0).asDiagonal();
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
}

TEST(DenseQpSolverTest, GivenCholeskyFactorGivesTheSameSolutionWithoutReadingH) {
  std::mt19937 rng(77);
  for (int trial = 0; trial < 10; ++trial) {
    // Given: a random constrained QP, and a copy carrying only the factor of H (H poisoned
    // with NaN in the copy, so any read of it would show), solved in sequence (warm starts)
    const DenseQp qp = RandomFeasibleQp(30, 60, &rng);
    DenseQp factored = qp;
    factored.L = qp.H.llt().matrixL();
    factored.L.triangularView<Eigen::StrictlyUpper>().setConstant(kNaNValue);
    factored.H.setConstant(kNaNValue);
    factored.h_factor_given = true;
    DenseQpSolver with_h(qp.dims());
    DenseQpSolver with_factor(qp.dims());
    QpSolution a(qp.dims());
    QpSolution b(qp.dims());
    for (int solve = 0; solve < 2; ++solve) {
      // When: both solve
      ASSERT_EQ(with_h.Solve(qp, &a), QpStatus::kOptimal);
      ASSERT_EQ(with_factor.Solve(factored, &b), QpStatus::kOptimal);
      // Then: the same solution, multipliers, objective, and KKT holds for the factor
      EXPECT_LT((a.x - b.x).lpNorm<Eigen::Infinity>(), 1e-9);
      EXPECT_LT((a.y_constraints - b.y_constraints).lpNorm<Eigen::Infinity>(), 1e-8);
      EXPECT_LT((a.y_bounds - b.y_bounds).lpNorm<Eigen::Infinity>(), 1e-8);
      EXPECT_NEAR(a.objective, b.objective, 1e-9 * (1.0 + std::abs(a.objective)));
      EXPECT_LE(ComputeKktResiduals(factored, b).Max(), kKktTol);
    }
    EXPECT_GT(b.num_active, 0);
  }
}

TEST(DenseQpSolverTest, BadGivenFactorIsAStatus) {
  DenseQpSolver solver(DenseQpDims{3, 0});
  QpSolution sol(DenseQpDims{3, 0});
  DenseQp qp(DenseQpDims{3, 0});
  qp.h_factor_given = true;
  qp.g << 1.0, 2.0, 3.0;
  // Given: a zero or negative pivot -> not convex
  qp.L = Eigen::Vector3d(1.0, 0.0, 2.0).asDiagonal();
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNotConvex);
  qp.L = Eigen::Vector3d(1.0, -1.0, 2.0).asDiagonal();
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNotConvex);
  // Given: NaN in the lower triangle -> numerical error
  qp.L.setIdentity();
  qp.L(2, 0) = kNaNValue;
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kNumericalError);
  // Given: wrong size -> invalid input
  qp.L = Eigen::MatrixXd::Identity(2, 2);
  EXPECT_EQ(solver.Solve(qp, &sol), QpStatus::kInvalidInput);
  // Given: a valid factor -> x = -(L L')^-1 g
  qp.L = Eigen::Vector3d(1.0, 2.0, 4.0).asDiagonal();
  ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
  EXPECT_LT((sol.x - Eigen::Vector3d(-1.0, -0.5, -3.0 / 16.0)).norm(), 1e-14);
}

TEST(DenseQpSolverTest, IterationCapGivesMaxIterations) {
  // Given: a QP with many active constraints and a cap of 2 changes
  std::mt19937 rng(71);
  RandomQpOptions opt;
  opt.g_scale = 50.0;
  const DenseQp qp = RandomFeasibleQp(20, 30, &rng, opt);
  QpSettings settings;
  settings.max_iterations = 2;
  DenseQpSolver capped(qp.dims(), settings);
  DenseQpSolver free_solver(qp.dims());
  QpSolution sol(qp.dims());
  ASSERT_EQ(free_solver.Solve(qp, &sol), QpStatus::kOptimal);
  ASSERT_GT(sol.iterations, 2);
  // When / Then
  EXPECT_EQ(capped.Solve(qp, &sol), QpStatus::kMaxIterations);
  EXPECT_LE(sol.iterations, 2);
  EXPECT_TRUE(sol.x.allFinite());
}

TEST(DenseQpSolverTest, ConstructorRejectsBadDimensionsAndSettings) {
  EXPECT_THROW(DenseQpSolver(DenseQpDims{0, 3}), std::invalid_argument);
  EXPECT_THROW(DenseQpSolver(DenseQpDims{3, -1}), std::invalid_argument);
  QpSettings bad;
  bad.tolerance = 0.0;
  EXPECT_THROW(DenseQpSolver(DenseQpDims{3, 1}, bad), std::invalid_argument);
  bad = QpSettings{};
  bad.max_iterations = 0;
  EXPECT_THROW(DenseQpSolver(DenseQpDims{3, 1}, bad), std::invalid_argument);
}

TEST(DenseQpSolverTest, KktResidualsFlagWrongMultipliers) {
  // Given: an optimal solution with active constraints
  std::mt19937 rng(81);
  const DenseQp qp = RandomFeasibleQp(10, 10, &rng);
  DenseQpSolver solver(qp.dims());
  QpSolution sol(qp.dims());
  ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
  ASSERT_GT(sol.num_active, 0);
  EXPECT_LE(ComputeKktResiduals(qp, sol).Max(), kKktTol);
  // When: the multipliers' sign is flipped
  QpSolution flipped = sol;
  flipped.y_bounds = -sol.y_bounds;
  flipped.y_constraints = -sol.y_constraints;
  // Then: the solver's residuals and the independent ones both flag it
  EXPECT_GT(ComputeKktResiduals(qp, flipped).Max(), 1e-3);
  EXPECT_GT(CheckKkt(qp, flipped).Max(), 1e-3);
  // When: x is moved outside a bound
  QpSolution shifted = sol;
  shifted.x.array() += 10.0;
  EXPECT_GT(ComputeKktResiduals(qp, shifted).primal, 1.0);
}

TEST(DenseQpSolverTest, StatusNames) {
  EXPECT_EQ(ToString(QpStatus::kOptimal), "optimal");
  EXPECT_EQ(ToString(QpStatus::kInfeasible), "infeasible");
  EXPECT_EQ(ToString(QpStatus::kNotConvex), "not_convex");
  EXPECT_EQ(ToString(QpStatus::kMaxIterations), "max_iterations");
}

// ---------------------------------------------------------------------------------------
// Warm start.

class WarmStartTest : public ::testing::TestWithParam<bool> {};

TEST_P(WarmStartTest, NeedsFewerActiveSetChangesInClosedLoop) {
  // Given: a closed-loop sequence of condensed MPC QPs (same H and A, shifted g and
  // constraint bounds), solved cold and warm (batch or sequential variant)
  const testing::MpcQpFactory mpc;
  QpSettings cold_settings;
  cold_settings.warm_start = false;
  QpSettings warm_settings;
  warm_settings.warm_start_batch = GetParam();
  const DenseQpDims dims{mpc.horizon, mpc.horizon};
  DenseQpSolver cold(dims, cold_settings);
  DenseQpSolver warm(dims, warm_settings);
  QpSolution cold_sol(dims);
  QpSolution warm_sol(dims);
  double p = 0.0;
  double v = 0.0;
  int cold_changes = 0;
  int warm_changes = 0;
  int warm_adds = 0;
  int active = 0;
  const int kSteps = 40;
  for (int step = 0; step < kSteps; ++step) {
    const DenseQp qp = mpc.Build(p, v);
    // When: both solvers solve the same QP
    ASSERT_EQ(cold.Solve(qp, &cold_sol), QpStatus::kOptimal) << "step " << step;
    ASSERT_EQ(warm.Solve(qp, &warm_sol), QpStatus::kOptimal) << "step " << step;
    // Then: same solution, valid KKT
    EXPECT_LE((cold_sol.x - warm_sol.x).lpNorm<Eigen::Infinity>(), 1e-7) << "step " << step;
    EXPECT_LE(CheckKkt(qp, warm_sol).Max(), kKktTol) << "step " << step;
    EXPECT_LE(CheckKkt(qp, cold_sol).Max(), kKktTol) << "step " << step;
    EXPECT_EQ(cold_sol.num_warm_start_adds, 0);
    cold_changes += cold_sol.iterations;
    warm_changes += warm_sol.iterations;
    warm_adds += warm_sol.num_warm_start_adds;
    active += warm_sol.num_active;
    mpc.Step(warm_sol.x[0], &p, &v);
  }
  // Then: the sequence is constrained, warm start is used and needs fewer changes
  EXPECT_GT(active, kSteps);
  EXPECT_GT(warm_adds, 0);
  EXPECT_LT(warm_changes, cold_changes);
  std::printf(
      "closed loop (%s): %d active on average, cold %d, warm %d active-set changes "
      "(%d warm-start adds)\n",
      GetParam() ? "batch" : "sequential", active / kSteps, cold_changes, warm_changes, warm_adds);
}

TEST_P(WarmStartTest, NeedsFewerActiveSetChangesOnDriftingRandomQps) {
  // Given: nv = 45, nc = 135; g, bounds and constraint sides drift a little per step
  std::mt19937 rng(97);
  RandomQpOptions opt;
  opt.g_scale = 5.0;
  opt.bound_width = 3.0;
  opt.row_width = 20.0;
  DenseQp qp = RandomFeasibleQp(45, 135, &rng, opt);
  const Eigen::VectorXd dg = 0.02 * Gaussian(45, 1, &rng);
  const Eigen::VectorXd db = 0.002 * Gaussian(45, 1, &rng);
  const Eigen::VectorXd dba = 0.002 * Gaussian(135, 1, &rng);
  QpSettings cold_settings;
  cold_settings.warm_start = false;
  QpSettings warm_settings;
  warm_settings.warm_start_batch = GetParam();
  DenseQpSolver cold(qp.dims(), cold_settings);
  DenseQpSolver warm(qp.dims(), warm_settings);
  QpSolution cold_sol(qp.dims());
  QpSolution warm_sol(qp.dims());
  int cold_changes = 0;
  int warm_changes = 0;
  int active = 0;
  const int kSteps = 30;
  for (int step = 0; step < kSteps; ++step) {
    // When
    ASSERT_EQ(cold.Solve(qp, &cold_sol), QpStatus::kOptimal) << "step " << step;
    ASSERT_EQ(warm.Solve(qp, &warm_sol), QpStatus::kOptimal) << "step " << step;
    // Then
    EXPECT_LE((cold_sol.x - warm_sol.x).lpNorm<Eigen::Infinity>(), 1e-7) << "step " << step;
    EXPECT_LE(CheckKkt(qp, warm_sol).Max(), kKktTol) << "step " << step;
    cold_changes += cold_sol.iterations;
    warm_changes += warm_sol.iterations;
    active += warm_sol.num_active;
    qp.g += dg;
    qp.lb += db;
    qp.ub += db;
    qp.lbA += dba;
    qp.ubA += dba;
  }
  EXPECT_GT(active, 3 * kSteps);
  EXPECT_LT(warm_changes, cold_changes);
  std::printf("drifting random QPs (%s): %d active on average, cold %d, warm %d changes\n",
              GetParam() ? "batch" : "sequential", active / kSteps, cold_changes, warm_changes);
}

INSTANTIATE_TEST_SUITE_P(Variants, WarmStartTest, ::testing::Bool());

TEST(DenseQpSolverTest, ResetWarmStartStartsCold) {
  // Given: a solved QP with active constraints
  std::mt19937 rng(91);
  const DenseQp qp = RandomFeasibleQp(15, 20, &rng);
  DenseQpSolver solver(qp.dims());
  QpSolution sol(qp.dims());
  ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
  ASSERT_GT(sol.num_active, 0);
  const Eigen::VectorXd x_first = sol.x;
  // When: solved again warm, then after a reset
  ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
  EXPECT_GT(sol.num_warm_start_adds, 0);
  EXPECT_EQ(sol.num_drops, 0);
  EXPECT_LE((sol.x - x_first).lpNorm<Eigen::Infinity>(), 1e-9);
  solver.ResetWarmStart();
  ASSERT_EQ(solver.Solve(qp, &sol), QpStatus::kOptimal);
  // Then
  EXPECT_EQ(sol.num_warm_start_adds, 0);
  EXPECT_LE((sol.x - x_first).lpNorm<Eigen::Infinity>(), 1e-9);
}

TEST(DenseQpSolverTest, MovedSolverKeepsWorking) {
  std::mt19937 rng(93);
  const DenseQp qp = RandomFeasibleQp(8, 6, &rng);
  DenseQpSolver a(qp.dims());
  DenseQpSolver b = std::move(a);
  QpSolution sol(qp.dims());
  EXPECT_EQ(b.Solve(qp, &sol), QpStatus::kOptimal);
  EXPECT_LE(CheckKkt(qp, sol).Max(), kKktTol);
}

}  // namespace
}  // namespace fnmpc::qp

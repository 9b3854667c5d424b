// SPDX-License-Identifier: BSD-3-Clause
// Built with EIGEN_RUNTIME_NO_MALLOC, with fnmpc/qp/dense_qp.cpp compiled into this binary
// (so that the solver's Eigen code carries the malloc check) and eigen_assert counting
// failures (eigen_assert_counter.hpp). Global operator new is replaced to count the
// allocations of non-Eigen code (std::vector, ...).

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <random>
#include <vector>

#include "fnmpc/qp/dense_qp.hpp"
#include "tests/qp/qp_test_problems.hpp"
#include "tests/support/allocation_counter.hpp"

#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "this test must be compiled with EIGEN_RUNTIME_NO_MALLOC"
#endif

namespace fnmpc::qp {
namespace {

using testing::g_eigen_assert_failures;

struct AllocationCount {
  int eigen = 0;  ///< Eigen heap allocations (failed malloc checks)
  int news = 0;   ///< global operator new calls
};

// Runs Solve with heap allocation forbidden and returns what was attempted.
AllocationCount GuardedSolve(DenseQpSolver* solver, const DenseQp& qp, QpSolution* sol,
                             QpStatus* status) {
  const int eigen_before = g_eigen_assert_failures.load();
  Eigen::internal::set_is_malloc_allowed(false);
  const long news = ::fnmpc::testing::CountAllocations([&] { *status = solver->Solve(qp, sol); });
  Eigen::internal::set_is_malloc_allowed(true);
  return {g_eigen_assert_failures.load() - eigen_before, static_cast<int>(news)};
}

TEST(DenseQpNoAllocTest, GuardDetectsAnAllocation) {
  // Given / When: an Eigen allocation inside the guard
  const int before = g_eigen_assert_failures.load();
  Eigen::internal::set_is_malloc_allowed(false);
  Eigen::VectorXd v(100);
  Eigen::internal::set_is_malloc_allowed(true);
  // Then: it is counted (the test below is able to fail)
  EXPECT_GT(g_eigen_assert_failures.load(), before);
  EXPECT_EQ(v.size(), 100);
}

TEST(DenseQpNoAllocTest, SolveDoesNotAllocate) {
  // Given: solvers and solutions built up front for the benchmark sizes
  std::mt19937 rng(5);
  const std::vector<std::pair<int, int>> sizes = {{45, 45}, {60, 135}, {60, 315}};
  for (const auto& [nv, nc] : sizes) {
    testing::RandomQpOptions opt;
    opt.equality_share = 0.05;
    std::vector<DenseQp> qps;
    for (int k = 0; k < 4; ++k) qps.push_back(testing::RandomFeasibleQp(nv, nc, &rng, opt));
    // An infeasible one and a non-convex one exercise the failure paths.
    DenseQp infeasible = qps[0];
    infeasible.A.row(1) = infeasible.A.row(2);
    infeasible.lbA[1] = infeasible.ubA[2] + 1.0;
    infeasible.ubA[1] = testing::kInfBound;
    DenseQp not_convex = qps[1];
    not_convex.H(0, 0) = -1.0;
    qps.push_back(infeasible);
    qps.push_back(not_convex);
    qps.push_back(qps[2]);
    qps.push_back(qps[2]);  // warm start from an identical problem
    DenseQpSolver solver(qps[0].dims());
    QpSolution sol(qps[0].dims());
    int active = 0;
    for (const DenseQp& qp : qps) {
      // When
      QpStatus status = QpStatus::kNumericalError;
      const AllocationCount count = GuardedSolve(&solver, qp, &sol, &status);
      // Then
      EXPECT_EQ(count.eigen, 0) << "nv " << nv << " nc " << nc;
      EXPECT_EQ(count.news, 0) << "nv " << nv << " nc " << nc;
      if (status == QpStatus::kOptimal) active += sol.num_active;
    }
    EXPECT_EQ(sol.status, QpStatus::kOptimal);
    EXPECT_GT(sol.num_warm_start_adds, 0);
    EXPECT_GT(active, 0);
  }
}

}  // namespace
}  // namespace fnmpc::qp

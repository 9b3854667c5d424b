// SPDX-License-Identifier: BSD-3-Clause
// A control step (shift, references, prepare, feedback) allocates nothing on the heap
// after construction: this binary replaces the global operator new to count.
#include <gtest/gtest.h>

#include <vector>

#include "bench/ocp_spec/benchmark_ocps.hpp"
#include "tests/support/allocation_counter.hpp"

namespace fnmpc::bench {
namespace {

TEST(RtiNoAllocTest, LeaderStepsDoNotAllocate) {
  // Given a constructed leader solver after its initial convergence
  const ReferenceTrajectory ref(Scenario::kAggressive);
  Vec<9> x = Vec<9>::Zero();
  x[2] = 1.0;
  auto solver = MakeLeaderSolver(x);
  SetLeaderReferences(&solver, ref, 0.0);
  Vec3 u;
  solver.Step(x, &u);
  // When control steps run along the aggressive reference (bounds active), the plant
  // being the predicted next node with a position disturbance (the velocity stays
  // reachable under the hard |v| <= 2 bound, so every QP is feasible)
  int steps_with_active_bounds = 0;
  int unconstrained_steps = 0;  // the Riccati step without condensing or QP
  // (then 140 steps holding the last waypoint without disturbance, where the QP's active
  // set empties and the unconstrained Riccati step takes over)
  const long allocations = ::fnmpc::testing::CountAllocations([&] {
    for (int k = 1; k < 200; ++k) {
      x = solver.states()[1];
      if (k < 60) x.head<3>() += Vec3(0.01, -0.005, 0.002);
      solver.Shift();
      SetLeaderReferences(&solver, ref, k < 60 ? k * 0.05 : 30.0);
      solver.Step(x, &u);
      unconstrained_steps += solver.stats().unconstrained_step ? 1 : 0;
      const auto& qp = solver.qp_solution();
      if (qp.y_bounds.cwiseAbs().maxCoeff() > 0.0 || qp.y_constraints.cwiseAbs().maxCoeff() > 0.0) {
        ++steps_with_active_bounds;
      }
    }
  });
  // Then nothing was allocated, bounds were active, both the QP and the unconstrained
  // Riccati step ran, and every QP was solved
  EXPECT_GT(steps_with_active_bounds, 0);
  EXPECT_GT(unconstrained_steps, 0);
  EXPECT_LT(unconstrained_steps, 199);
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(solver.stats().fallback_count, 0);
}

TEST(RtiNoAllocTest, FollowerStepsDoNotAllocate) {
  std::array<NeighbourState, 2> nb{NeighbourState{kD1, Vec3(0.3, 0, 0)},
                                   NeighbourState{kD2, Vec3(0.3, 0, 0)}};
  auto solver = MakeFollowerSolver<2>(Vec<6>::Zero(), nb);
  Vec3 u;
  solver.Step(FollowerState<2>(Vec<6>::Zero(), nb), &u);
  auto reduced = MakeReducedFollowerSolver<2>(Vec<6>::Zero(), nb);
  reduced.Step(SetReducedFollowerStage<2>(&reduced, Vec<6>::Zero(), nb), &u);
  // F6: the Riccati recursion on its cost-relevant states (compact matrices)
  std::array<NeighbourState, 6> nb6{};
  for (int j = 0; j < 6; ++j) nb6[j] = NeighbourState{Vec3(0.5 * j, 1.0, 0.0), Vec3::Zero()};
  nb6[0] = nb[0];
  nb6[1] = nb[1];
  auto six = MakeFollowerSolver<6>(Vec<6>::Zero(), nb6);
  six.Step(FollowerState<6>(Vec<6>::Zero(), nb6), &u);
  const long allocations = ::fnmpc::testing::CountAllocations([&] {
    for (int k = 1; k < 30; ++k) {
      solver.Shift();
      solver.Step(FollowerState<2>(Vec<6>::Zero(), nb), &u);
      reduced.Shift();
      reduced.Step(SetReducedFollowerStage<2>(&reduced, Vec<6>::Zero(), nb), &u);
      six.Shift();
      six.Step(FollowerState<6>(Vec<6>::Zero(), nb6), &u);
    }
  });
  EXPECT_EQ(allocations, 0);
}

TEST(RtiNoAllocTest, CounterSeesAllocations) {
  // The counter itself works (guards the tests above against a silent no-op).
  std::vector<double>* p = nullptr;
  const long allocations =
      ::fnmpc::testing::CountAllocations([&] { p = new std::vector<double>(100); });
  delete p;
  EXPECT_GE(allocations, 1);
}

}  // namespace
}  // namespace fnmpc::bench

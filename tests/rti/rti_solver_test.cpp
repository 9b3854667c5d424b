// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/rti/rti_solver.hpp"

#include <gtest/gtest.h>

#include "bench/ocp_spec/benchmark_ocps.hpp"

namespace fnmpc::bench {
namespace {

Vec<9> Hover(const Vec3& p) {
  Vec<9> x = Vec<9>::Zero();
  x.head<3>() = p;
  return x;
}

TEST(RtiSolverTest, FirstCallConvergesBelowKktThreshold) {
  // Given the leader 1 m away from its reference
  auto solver = MakeLeaderSolver(Hover(Vec3(1, 0, 1)));
  SetLeaderReferences(&solver, ReferenceTrajectory(Scenario::kNominal), 0.0);
  Vec3 u;
  // When the first call runs (Algorithm 1, t = 0)
  const rti::RtiStatus status = solver.Step(Hover(Vec3(1, 0, 1)), &u);
  // Then it iterated to KKT < 1e-6 and moves towards the reference
  EXPECT_EQ(status, rti::RtiStatus::kSuccess);
  EXPECT_GT(solver.stats().sqp_iterations, 1);
  EXPECT_LT(solver.stats().kkt, 1e-6);
  EXPECT_LT(u[2], 0.0);                   // negative pitch accelerates towards -x
  EXPECT_LT(solver.states()[5][0], 1.0);  // predicted x decreases towards 0
}

TEST(RtiSolverTest, LaterCallsDoOneIterationByDefault) {
  auto solver = MakeLeaderSolver(Hover(Vec3(0, 0, 1)));
  const ReferenceTrajectory ref(Scenario::kNominal);
  SetLeaderReferences(&solver, ref, 0.0);
  Vec3 u;
  solver.Step(Hover(Vec3(0, 0, 1)), &u);
  solver.Shift();
  SetLeaderReferences(&solver, ref, 0.05);
  solver.Step(Hover(Vec3(0, 0, 1)), &u);
  EXPECT_EQ(solver.stats().sqp_iterations, 1);
}

TEST(RtiSolverTest, MoreIterationsWithinBudgetReachThreshold) {
  rti::RtiSettings settings = SpecSettings();
  settings.max_iterations = 20;
  auto solver = MakeLeaderSolver(Hover(Vec3(0, 0, 1)), settings);
  const ReferenceTrajectory ref(Scenario::kNominal);
  SetLeaderReferences(&solver, ref, 0.0);
  Vec3 u;
  solver.Step(Hover(Vec3(0, 0, 1)), &u);
  solver.Shift();
  SetLeaderReferences(&solver, ref, 1.0);  // a jump in the reference
  solver.Step(Hover(Vec3(0.1, 0, 1)), &u);
  EXPECT_GT(solver.stats().sqp_iterations, 1);
  EXPECT_LT(solver.stats().kkt, settings.kkt_threshold);
}

TEST(RtiSolverTest, NanStateFallsBackToShiftedSolution) {
  // Given a converged solver
  auto solver = MakeLeaderSolver(Hover(Vec3(0.5, 0, 1)));
  SetLeaderReferences(&solver, ReferenceTrajectory(Scenario::kNominal), 0.0);
  Vec3 u;
  solver.Step(Hover(Vec3(0.5, 0, 1)), &u);
  solver.Shift();
  const Vec3 shifted = solver.inputs()[0];
  // When the state estimate is NaN
  Vec<9> bad = Hover(Vec3(0.5, 0, 1));
  bad[4] = kNaN;
  const rti::RtiStatus status = solver.Step(bad, &u);
  // Then the shifted previous solution is applied, flagged and counted, never NaN
  EXPECT_EQ(status, rti::RtiStatus::kInvalidInput);
  EXPECT_TRUE(solver.stats().fallback);
  EXPECT_EQ(solver.stats().fallback_count, 1);
  EXPECT_TRUE(u.allFinite());
  EXPECT_EQ(u, shifted);
}

TEST(RtiSolverTest, InfeasibleQpFallsBack) {
  // Given contradictory hard velocity bounds at one stage
  auto solver = MakeLeaderSolver(Hover(Vec3(0, 0, 1)));
  SetLeaderReferences(&solver, ReferenceTrajectory(Scenario::kNominal), 0.0);
  Vec3 u;
  solver.Step(Hover(Vec3(0, 0, 1)), &u);
  solver.Shift();
  Vec<9> lb = Vec<9>::Constant(-kInf), ub = Vec<9>::Constant(kInf);
  lb[3] = 1.0;  // v_x >= 1 at node 1: unreachable from rest in 0.05 s with the tilt bound
  ub[3] = 2.0;
  solver.SetStateBounds(1, lb, ub);
  const Vec3 shifted = solver.inputs()[0];
  const rti::RtiStatus status = solver.Step(Hover(Vec3(0, 0, 1)), &u);
  EXPECT_EQ(status, rti::RtiStatus::kQpFailure);
  EXPECT_EQ(solver.stats().qp_status, qp::QpStatus::kInfeasible);
  EXPECT_TRUE(solver.stats().fallback);
  EXPECT_EQ(u, shifted);
}

TEST(RtiSolverTest, SoftRelativeBoundsKeepQpFeasibleOutsideBounds) {
  // Given a follower pushed 1 m beyond its relative-position safety bound
  std::array<NeighbourState, 2> nb{NeighbourState{Vec3(7.0, 1, 0), Vec3::Zero()},
                                   NeighbourState{Vec3(6.0, 2, 0), Vec3::Zero()}};
  auto solver = MakeFollowerSolver<2>(Vec<6>::Zero(), nb);
  Vec3 u;
  // When it solves
  const rti::RtiStatus status = solver.Step(FollowerState<2>(Vec<6>::Zero(), nb), &u);
  // Then the QP stays feasible, the slack absorbs the violation, and the follower
  // moves back inside (towards +x)
  EXPECT_EQ(status, rti::RtiStatus::kSuccess);
  EXPECT_GT(solver.slack(1), 0.5);
  EXPECT_LT(solver.states()[15][6], 7.0);
}

TEST(RtiSolverTest, SoftBoundIsExactWhenFeasible) {
  // Given a follower in formation and a soft bound dx_1,x <= 0.9 from node 10 on, below
  // the desired 1.0: reachable in 0.5 s, so the hard problem is feasible
  std::array<NeighbourState, 2> nb{NeighbourState{kD1, Vec3::Zero()},
                                   NeighbourState{kD2, Vec3::Zero()}};
  rti::RtiSettings settings = SpecSettings();
  settings.max_initial_iterations = 100;
  auto solver = MakeFollowerSolver<2>(Vec<6>::Zero(), nb, settings);
  Vec<22> lb = solver.lower_state_bound(1), ub = solver.upper_state_bound(1);
  ub[6] = 0.9;
  for (int k = 10; k <= 15; ++k) solver.SetStateBounds(k, lb, ub);
  Vec3 u;
  // When it converges
  ASSERT_EQ(solver.Step(FollowerState<2>(Vec<6>::Zero(), nb), &u), rti::RtiStatus::kSuccess);
  // Then the bound is active and met without slack: the exact penalty is exact
  double worst = -kInf;
  for (int k = 10; k <= 15; ++k) worst = std::max(worst, solver.states()[k][6] - 0.9);
  EXPECT_GT(worst, -1e-6);
  EXPECT_LT(worst, 1e-6);
  for (int k = 1; k <= 15; ++k) EXPECT_LT(solver.slack(k), 1e-8) << "node " << k;
}

TEST(RtiSolverTest, InvalidSettingsAreRejected) {
  rti::RtiSettings s;
  s.horizon = 0;
  EXPECT_THROW(MakeLeaderSolver(Hover(Vec3::Zero()), s), std::invalid_argument);
  s = rti::RtiSettings{};
  s.sample_time = -0.05;
  EXPECT_THROW(MakeLeaderSolver(Hover(Vec3::Zero()), s), std::invalid_argument);
  EXPECT_THROW(
      (rti::RtiSolver<ocp::LeaderProblem>({}, rti::RtiSettings{}, {{3, 42}, {false, false}})),
      std::invalid_argument);
}

// ---- Closed loop: the quality goals of the benchmark spec ----

TEST(RtiClosedLoopTest, LeaderNominalTracksWithinSpec) {
  const auto r = RunClosedLoop(ProblemId::kL, Scenario::kNominal);
  const auto s = Summarize(r);
  EXPECT_EQ(s.fallbacks, 0);
  EXPECT_LE(s.rms_error_m, 0.003);
  EXPECT_LT(r.initial_kkt, 1e-6);
  EXPECT_LE(s.max_input_violation, 1e-9);
}

TEST(RtiClosedLoopTest, FollowerNominalKeepsFormationWithinSpec) {
  for (ProblemId p : {ProblemId::kF2, ProblemId::kF2Reduced}) {
    const auto s = Summarize(RunClosedLoop(p, Scenario::kNominal));
    EXPECT_EQ(s.fallbacks, 0) << ToString(p);
    EXPECT_LE(s.rms_error_m, 0.03) << ToString(p);
  }
}

TEST(RtiClosedLoopTest, AggressiveScenarioRespectsBounds) {
  for (ProblemId p : {ProblemId::kL, ProblemId::kF2Reduced}) {
    const auto s = Summarize(RunClosedLoop(p, Scenario::kAggressive));
    EXPECT_EQ(s.fallbacks, 0) << ToString(p);
    EXPECT_LE(s.max_input_violation, 1e-9) << ToString(p);
    EXPECT_LE(s.max_hard_state_violation, 1e-6) << ToString(p);
  }
}

TEST(RtiClosedLoopTest, UnconstrainedShortcutGivesTheSameLoop) {
  for (ProblemId p : {ProblemId::kL, ProblemId::kF2, ProblemId::kF6, ProblemId::kF2Reduced}) {
    for (Scenario sc : {Scenario::kNominal, Scenario::kAggressive}) {
      // Given: the same closed loop with and without the unconstrained Riccati step
      rti::RtiSettings off = SpecSettings();
      off.unconstrained_shortcut = false;
      const auto with = RunClosedLoop(p, sc, 260);
      const auto without = RunClosedLoop(p, sc, 260, off);
      // Then: the same errors, KKT values and QP iterations step by step, and the
      // shortcut was taken in some steps (never without it) and not in others when
      // bounds are active
      int taken = 0;
      for (std::size_t k = 0; k < with.steps.size(); ++k) {
        const auto& a = with.steps[k];
        const auto& b = without.steps[k];
        EXPECT_NEAR(a.error_m, b.error_m, 1e-9) << ToString(p) << " step " << k;
        EXPECT_NEAR(a.kkt, b.kkt, 1e-7 * (1.0 + b.kkt)) << ToString(p) << " step " << k;
        EXPECT_EQ(a.qp_iterations, b.qp_iterations) << ToString(p) << " step " << k;
        EXPECT_FALSE(b.unconstrained_step);
        taken += a.unconstrained_step ? 1 : 0;
      }
      if (sc == Scenario::kNominal) {
        EXPECT_GT(taken, 250) << ToString(p);
      } else {
        EXPECT_GT(taken, 0) << ToString(p);
        EXPECT_LT(taken, 200) << ToString(p);
      }
      EXPECT_EQ(with.fallbacks, 0);
    }
  }
}

TEST(RtiClosedLoopTest, ReducedAndFullFollowersFlyTheSameLoop) {
  // Same discretisation and optimum: the closed loops agree (not bit for bit: the
  // RTI iterates differ in how neighbour states enter the guess).
  // F6 runs the Riccati recursion on its 22 cost-relevant states only (its four static
  // neighbours have zero weight), F2 on all 22, the reduced ones on 9.
  for (const auto& [f, r] : {std::pair{ProblemId::kF2, ProblemId::kF2Reduced},
                             std::pair{ProblemId::kF6, ProblemId::kF6Reduced}}) {
    for (Scenario sc : {Scenario::kNominal, Scenario::kAggressive}) {
      const auto full = RunClosedLoop(f, sc, 200);
      const auto reduced = RunClosedLoop(r, sc, 200);
      for (std::size_t k = 0; k < full.steps.size(); ++k) {
        EXPECT_NEAR(full.steps[k].error_m, reduced.steps[k].error_m, 1e-6)
            << ToString(f) << " step " << k;
      }
    }
  }
}

}  // namespace
}  // namespace fnmpc::bench

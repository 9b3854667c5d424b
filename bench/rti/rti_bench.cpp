// SPDX-License-Identifier: BSD-3-Clause
// One control step (shift + references + prepare + feedback) and the feedback phase alone
// of each benchmark problem, mid-way through the nominal scenario.
#include <benchmark/benchmark.h>

#include "bench/ocp_spec/benchmark_ocps.hpp"

namespace fnmpc::bench {
namespace {

void BM_LeaderStep(::benchmark::State& state) {
  const ReferenceTrajectory ref(Scenario::kNominal);
  Vec<9> x = Vec<9>::Zero();
  x[2] = 1.0;
  auto solver = MakeLeaderSolver(x);
  SetLeaderReferences(&solver, ref, 0.0);
  Vec3 u;
  solver.Step(x, &u);
  int k = 0;
  for (auto _ : state) {
    ++k;
    solver.Shift();
    SetLeaderReferences(&solver, ref, 2.0 + 0.05 * (k % 40));
    solver.Step(x, &u);
    ::benchmark::DoNotOptimize(u);
  }
}
BENCHMARK(BM_LeaderStep);

void BM_LeaderFeedback(::benchmark::State& state) {
  const ReferenceTrajectory ref(Scenario::kNominal);
  Vec<9> x = Vec<9>::Zero();
  x[2] = 1.0;
  auto solver = MakeLeaderSolver(x);
  SetLeaderReferences(&solver, ref, 0.0);
  Vec3 u;
  solver.Step(x, &u);
  for (auto _ : state) {
    state.PauseTiming();
    solver.Shift();
    SetLeaderReferences(&solver, ref, 2.0);
    solver.Prepare();
    state.ResumeTiming();
    solver.Feedback(x, &u);
    ::benchmark::DoNotOptimize(u);
  }
}
BENCHMARK(BM_LeaderFeedback);

template <int Nn, bool kReduced>
void BM_FollowerStep(::benchmark::State& state) {
  std::array<NeighbourState, Nn> nb;
  nb.fill(NeighbourState{Vec3(1, 1, 0), Vec3(0.4, 0.1, 0)});
  nb[1].rel_pos = kD2;
  const Vec<6> own = Vec<6>::Zero();
  if constexpr (kReduced) {
    auto solver = MakeReducedFollowerSolver<Nn>(own, nb);
    Vec3 u;
    solver.Step(SetReducedFollowerStage<Nn>(&solver, own, nb), &u);
    for (auto _ : state) {
      solver.Shift();
      solver.Step(SetReducedFollowerStage<Nn>(&solver, own, nb), &u);
      ::benchmark::DoNotOptimize(u);
    }
  } else {
    auto solver = MakeFollowerSolver<Nn>(own, nb);
    Vec3 u;
    solver.Step(FollowerState<Nn>(own, nb), &u);
    for (auto _ : state) {
      solver.Shift();
      solver.Step(FollowerState<Nn>(own, nb), &u);
      ::benchmark::DoNotOptimize(u);
    }
  }
}
BENCHMARK(BM_FollowerStep<2, false>)->Name("BM_F2Step");
BENCHMARK(BM_FollowerStep<6, false>)->Name("BM_F6Step");
BENCHMARK(BM_FollowerStep<2, true>)->Name("BM_F2ReducedStep");
BENCHMARK(BM_FollowerStep<6, true>)->Name("BM_F6ReducedStep");

}  // namespace
}  // namespace fnmpc::bench

// SPDX-License-Identifier: BSD-3-Clause
// BM_QpSolve: dense Goldfarb-Idnani solver on random strictly convex QPs with a few active
// constraints, cold and warm started, over a slowly drifting sequence of QPs (same H, A
// and bounds, shifted g) as in a real-time MPC loop. Counters: median/max per-solve wall
// time [us], active-set changes and active constraints per solve.

#include <benchmark/benchmark.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <random>
#include <vector>

#include "fnmpc/qp/dense_qp.hpp"
#include "tests/qp/qp_test_problems.hpp"

namespace fnmpc::qp {
namespace {

constexpr int kSequenceLength = 32;
constexpr int kCutConstraints = 4;

// QP sequence whose constraints lie around the unconstrained minimiser except
// kCutConstraints rows and two bounds that cut it off.
std::vector<DenseQp> MakeSequence(int nv, int nc, unsigned seed) {
  std::mt19937 rng(seed);
  DenseQp qp(DenseQpDims{nv, nc});
  qp.H = testing::RandomSpd(nv, 1.0, &rng);
  qp.g = testing::Gaussian(nv, 1, &rng);
  const Eigen::VectorXd x_free = qp.H.ldlt().solve(-qp.g);
  qp.A = testing::Gaussian(nc, nv, &rng);
  const Eigen::VectorXd ax = qp.A * x_free;
  for (int i = 0; i < nc; ++i) {
    const double scale = qp.A.row(i).norm();
    qp.lbA[i] = ax[i] - scale * testing::Uniform(1.0, 3.0, &rng);
    qp.ubA[i] = ax[i] + scale * testing::Uniform(1.0, 3.0, &rng);
  }
  for (int i = 0; i < std::min(nc, kCutConstraints); ++i) {
    qp.ubA[i] = ax[i] - 0.1 * qp.A.row(i).norm();
  }
  for (int j = 0; j < nv; ++j) {
    qp.lb[j] = x_free[j] - testing::Uniform(1.0, 3.0, &rng);
    qp.ub[j] = x_free[j] + testing::Uniform(1.0, 3.0, &rng);
  }
  qp.ub[0] = x_free[0] - 0.05;
  qp.lb[1] = x_free[1] + 0.05;
  const Eigen::VectorXd drift = 0.01 * testing::Gaussian(nv, 1, &rng);
  std::vector<DenseQp> seq;
  for (int k = 0; k < kSequenceLength; ++k) {
    seq.push_back(qp);
    qp.g += drift;
  }
  return seq;
}

void BM_QpSolve(benchmark::State& state) {
  const int nv = static_cast<int>(state.range(0));
  const int nc = static_cast<int>(state.range(1));
  QpSettings settings;
  settings.warm_start = state.range(2) != 0;
  const std::vector<DenseQp> seq = MakeSequence(nv, nc, 2024);
  DenseQpSolver solver(DenseQpDims{nv, nc}, settings);
  QpSolution sol(DenseQpDims{nv, nc});
  std::vector<double> times_us;
  times_us.reserve(1 << 22);
  long changes = 0;
  long active = 0;
  long solves = 0;
  bool ok = true;
  for (int k = 0; k < kSequenceLength; ++k) solver.Solve(seq[k], &sol);  // prime warm start
  std::size_t k = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const QpStatus status = solver.Solve(seq[k], &sol);
    const auto t1 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(sol.x.data());
    if (times_us.size() < times_us.capacity()) {
      times_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    }
    ok = ok && status == QpStatus::kOptimal;
    changes += sol.iterations;
    active += sol.num_active;
    ++solves;
    k = (k + 1) % seq.size();
  }
  if (!ok) state.SkipWithError("a QP was not solved to optimality");
  std::sort(times_us.begin(), times_us.end());
  if (!times_us.empty()) {
    state.counters["median_us"] = times_us[times_us.size() / 2];
    state.counters["max_us"] = times_us.back();
  }
  state.counters["changes"] = static_cast<double>(changes) / std::max(1L, solves);
  state.counters["active"] = static_cast<double>(active) / std::max(1L, solves);
  state.SetLabel(settings.warm_start ? "warm" : "cold");
}

BENCHMARK(BM_QpSolve)
    ->ArgNames({"nv", "nc", "warm"})
    ->Args({45, 45, 0})
    ->Args({45, 45, 1})
    ->Args({60, 135, 0})
    ->Args({60, 135, 1})
    ->Args({60, 315, 0})
    ->Args({60, 315, 1})
    ->Unit(benchmark::kMicrosecond);

// Lower bound for comparison: Cholesky + two triangular solves + one pass A x.
void BM_CholeskyAndPass(benchmark::State& state) {
  const int nv = static_cast<int>(state.range(0));
  const int nc = static_cast<int>(state.range(1));
  const std::vector<DenseQp> seq = MakeSequence(nv, nc, 2024);
  Eigen::LLT<Eigen::MatrixXd> llt(nv);
  Eigen::VectorXd x(nv);
  Eigen::VectorXd ax(nc);
  for (auto _ : state) {
    llt.compute(seq[0].H);
    x = -seq[0].g;
    llt.solveInPlace(x);
    ax.noalias() = seq[0].A * x;
    benchmark::DoNotOptimize(ax.data());
  }
}
BENCHMARK(BM_CholeskyAndPass)
    ->ArgNames({"nv", "nc"})
    ->Args({45, 45})
    ->Args({60, 135})
    ->Args({60, 315})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fnmpc::qp

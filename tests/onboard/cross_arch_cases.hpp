// SPDX-License-Identifier: BSD-3-Clause
#pragma once
// The figures that the cross-architecture test compares between the build machine (x86-64)
// and the onboard computer (aarch64): the closed loops of the benchmark problems L, F2, F6,
// F2-reduced and F6-reduced in both scenarios (fnmpc::bench::RunClosedLoop, 520
// control steps each), sampled every kEvery-th step and at the last one. cross_arch_reference
// writes them as CSV (tests/onboard/cross_arch_reference.csv, made by an x86-64 Release build);
// cross_arch_test recomputes them and compares (docs/onboard.md, "Results against x86-64").

#include <cstdio>
#include <string>
#include <vector>

#include "bench/ocp_spec/benchmark_ocps.hpp"

namespace fnmpc::onboard_testing {

inline constexpr int kEvery = 4;

struct CrossArchRow {
  std::string problem;
  std::string scenario;
  int step = 0;
  double error_m = 0;  ///< closed-loop tracking error after the step
  double kkt = 0;      ///< KKT value after the step
  int qp_iterations = 0;
};

inline std::vector<CrossArchRow> ComputeCrossArchRows() {
  namespace bm = fnmpc::bench;
  std::vector<CrossArchRow> rows;
  for (bm::ProblemId p : bm::kAllProblems) {
    for (bm::Scenario s : {bm::Scenario::kNominal, bm::Scenario::kAggressive}) {
      const bm::ClosedLoopResult r = bm::RunClosedLoop(p, s);
      const int n = static_cast<int>(r.steps.size());
      for (int k = 0; k < n; ++k) {
        if (k % kEvery != 0 && k != n - 1) continue;
        const bm::StepRecord& rec = r.steps[static_cast<std::size_t>(k)];
        rows.push_back({std::string(bm::ToString(p)), std::string(bm::ToString(s)), k, rec.error_m,
                        rec.kkt, rec.qp_iterations});
      }
    }
  }
  return rows;
}

inline void WriteCrossArchRows(const std::vector<CrossArchRow>& rows, std::FILE* out) {
  std::fprintf(out, "problem,scenario,step,error_m,kkt,qp_iterations\n");
  for (const CrossArchRow& r : rows) {
    std::fprintf(out, "%s,%s,%d,%.17g,%.17g,%d\n", r.problem.c_str(), r.scenario.c_str(), r.step,
                 r.error_m, r.kkt, r.qp_iterations);
  }
}

}  // namespace fnmpc::onboard_testing

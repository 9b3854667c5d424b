// SPDX-License-Identifier: BSD-3-Clause
// One control step of the VehicleController in the NMPC phase (command path only, then the
// diagnostics apart): a follower with 2 neighbours hovering in formation, with and without
// the input-rate and collision terms active, and with the disturbance observer's external
// acceleration in the prediction, and with the neighbours' predicted wakes (compensation level
// `wake`). Target: <= 20 us median (docs/benchmarks.md "Controller control step"). Time: the
// controller's call alone (manual timing with the steady clock); CPU: the whole loop, with the
// scenario's plant step and estimate synthesis. The scenario: control_step_scenario.hpp; its
// instruction counts: controller_step_count.
//   ./build/bench/formation/controller_bench
#include <benchmark/benchmark.h>

#include <chrono>

#include "bench/formation/control_step_scenario.hpp"

namespace {

void ControlStep(benchmark::State& state, bool rate, bool close, bool observer = false,
                 bool wake = false) {
  fnmpc::bench::ControlStepScenario s({rate, close, observer, wake});
  for (auto _ : state) {
    double seconds = 0.0;
    const fnmpc::formation::ControlOutput o = s.Step([&](auto&& control) {
      const auto start = std::chrono::steady_clock::now();
      const fnmpc::formation::ControlOutput out = control();
      seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      return out;
    });
    benchmark::DoNotOptimize(o.thrust);
    state.SetIterationTime(seconds);
  }
  state.counters["fallbacks"] = static_cast<double>(s.controller().fallbacks());
}

}  // namespace

BENCHMARK_CAPTURE(ControlStep, follower2_plain, false, false)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate, true, false)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision, true, true)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_observer, false, false, true)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision_observer, true, true, true)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_wake, false, false, true, true)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision_wake, true, true, true, true)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

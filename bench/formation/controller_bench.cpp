// SPDX-License-Identifier: BSD-3-Clause
// One control step of the VehicleController in the NMPC phase (command path only, then the
// diagnostics apart): a follower with 2 neighbours hovering in formation, with and without
// the input-rate and collision terms active, and with the disturbance observer's external
// acceleration in the prediction, and with the neighbours' predicted wakes (issue #17). Goal
// of issues #20/#17: <= 20 us median. The scenario: control_step_scenario.hpp; its
// instruction counts: controller_step_count.
//   ./build/bench/formation/controller_bench
#include <benchmark/benchmark.h>

#include "bench/formation/control_step_scenario.hpp"

namespace {

void ControlStep(benchmark::State& state, bool rate, bool close, bool observer = false,
                 bool wake = false) {
  fnmpc::bench::ControlStepScenario s({rate, close, observer, wake});
  for (auto _ : state) {
    const fnmpc::formation::ControlOutput o = s.Step();
    benchmark::DoNotOptimize(o.thrust);
  }
  state.counters["fallbacks"] = static_cast<double>(s.controller().fallbacks());
}

}  // namespace

BENCHMARK_CAPTURE(ControlStep, follower2_plain, false, false)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate, true, false)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision, true, true)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_observer, false, false, true)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision_observer, true, true, true)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_wake, false, false, true, true)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ControlStep, follower2_rate_collision_wake, true, true, true, true)
    ->Unit(benchmark::kMicrosecond);

// SPDX-License-Identifier: BSD-3-Clause
// The control steps of controller_bench for instruction counts, which a loaded machine does
// not disturb as it does wall times: builds a variant (plain, rate, rate_collision, observer,
// rate_collision_observer, wake, rate_collision_wake), flies it to steady NMPC flight and
// runs `steps` more control steps in MeasuredSteps(), the function callgrind collects:
//   valgrind --tool=callgrind --collect-atstart=no --toggle-collect='*MeasuredSteps*'
//       ./build/bench/formation/controller_step_count rate_collision_wake 1000
// (one command line).
// Instructions per control step: the "Collected" count over `steps` (it includes the plant's
// step, about 4 % of it: see docs/benchmarks.md).
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "bench/formation/control_step_scenario.hpp"

namespace {

// Not inlined: callgrind's --toggle-collect names it.
[[gnu::noinline]] double MeasuredSteps(fnmpc::bench::ControlStepScenario* s, long steps) {
  double sum = 0.0;
  for (long i = 0; i < steps; ++i) sum += s->Step().thrust;
  return sum;
}

}  // namespace

int main(int argc, char** argv) {
  using fnmpc::bench::ControlStepVariant;
  const std::string_view name = argc > 1 ? argv[1] : "rate_collision_wake";
  const long steps = argc > 2 ? std::atol(argv[2]) : 1000;
  ControlStepVariant v;
  if (name == "plain") {
  } else if (name == "rate") {
    v.rate = true;
  } else if (name == "rate_collision") {
    v = {true, true, false, false};
  } else if (name == "observer") {
    v.observer = true;
  } else if (name == "rate_collision_observer") {
    v = {true, true, true, false};
  } else if (name == "wake") {
    v.wake = true;
  } else if (name == "rate_collision_wake") {
    v = {true, true, true, true};
  } else {
    std::fprintf(stderr, "unknown variant '%.*s'\n", static_cast<int>(name.size()), name.data());
    return 2;
  }
  if (steps < 1) {
    std::fprintf(stderr, "steps must be >= 1\n");
    return 2;
  }
  fnmpc::bench::ControlStepScenario s(v);
  const double sum = MeasuredSteps(&s, steps);
  std::printf("%s: %ld steps, mean thrust %.6f N, %ld fallbacks\n", std::string(name).c_str(),
              steps, sum / static_cast<double>(steps), s.controller().fallbacks());
  return 0;
}

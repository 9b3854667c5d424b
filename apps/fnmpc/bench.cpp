// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc bench`: the closed-loop solver benchmark of docs/benchmark-spec.md.
#include <fmt/core.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "bench/ocp_spec/benchmark_ocps.hpp"

namespace fnmpc::app {
namespace {

using bench::ProblemId;
using bench::Scenario;

struct BenchOptions {
  bool json = false;
  std::vector<std::string> problems;
  std::vector<std::string> scenarios;
  int steps = -1;
};

nlohmann::json ToJson(const bench::ClosedLoopResult& r, const bench::ClosedLoopSummary& s) {
  return {{"problem", std::string(ToString(r.problem))},
          {"scenario", std::string(ToString(r.scenario))},
          {"steps", r.steps.size()},
          {"step_median_us", s.step_median_us},
          {"step_p99_us", s.step_p99_us},
          {"step_max_us", s.step_max_us},
          {"feedback_median_us", s.feedback_median_us},
          {"qp_iterations_median", s.qp_iterations_median},
          {"qp_iterations_max", s.qp_iterations_max},
          {"kkt_median", s.kkt_median},
          {"kkt_max", s.kkt_max},
          {"rms_error_m", s.rms_error_m},
          {"fallbacks", s.fallbacks},
          {"unconstrained_steps", s.unconstrained_steps},
          {"initial_sqp_iterations", r.initial_iterations},
          {"initial_kkt", r.initial_kkt},
          {"max_input_violation", s.max_input_violation},
          {"max_hard_state_violation", s.max_hard_state_violation}};
}

int Run(const BenchOptions& o) {
  std::vector<ProblemId> problems;
  for (ProblemId p : bench::kAllProblems) {
    if (o.problems.empty() ||
        std::find(o.problems.begin(), o.problems.end(), ToString(p)) != o.problems.end()) {
      problems.push_back(p);
    }
  }
  std::vector<Scenario> scenarios;
  for (Scenario s : {Scenario::kNominal, Scenario::kAggressive}) {
    if (o.scenarios.empty() ||
        std::find(o.scenarios.begin(), o.scenarios.end(), ToString(s)) != o.scenarios.end()) {
      scenarios.push_back(s);
    }
  }
  nlohmann::json out = nlohmann::json::array();
  if (!o.json) {
    fmt::print("{:<11} {:<10} {:>9} {:>9} {:>9} {:>9} {:>6} {:>9} {:>9} {:>9} {:>5} {:>5}\n",
               "problem", "scenario", "med[us]", "p99[us]", "max[us]", "fb[us]", "qp-it", "kkt-med",
               "kkt-max", "rms[m]", "fall", "ricc");
  }
  for (Scenario sc : scenarios) {
    for (ProblemId p : problems) {
      const auto r = bench::RunClosedLoop(p, sc, o.steps);
      const auto s = bench::Summarize(r);
      if (o.json) {
        out.push_back(ToJson(r, s));
      } else {
        fmt::print(
            "{:<11} {:<10} {:>9.1f} {:>9.1f} {:>9.1f} {:>9.2f} {:>6.0f} {:>9.1e} {:>9.1e} "
            "{:>9.5f} {:>5} {:>5}\n",
            ToString(p), ToString(sc), s.step_median_us, s.step_p99_us, s.step_max_us,
            s.feedback_median_us, s.qp_iterations_median, s.kkt_median, s.kkt_max, s.rms_error_m,
            s.fallbacks, s.unconstrained_steps);
        std::fflush(stdout);
      }
    }
  }
  if (o.json) fmt::print("{}\n", out.dump(2));
  return 0;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App* sub =
      app.add_subcommand("bench",
                         "Closed-loop solver benchmark (docs/benchmark-spec.md): L, F2, F6 and the "
                         "reduced F2/F6, nominal and aggressive scenarios");
  sub->add_flag("--json", o->json, "print a JSON array, one object per problem and scenario");
  sub->add_option("--problem", o->problems, "problems to run (default: all)")
      ->check(CLI::IsMember({"L", "F2", "F6", "F2-reduced", "F6-reduced"}));
  sub->add_option("--scenario", o->scenarios, "scenarios to run (default: both)")
      ->check(CLI::IsMember({"nominal", "aggressive"}));
  sub->add_option("--steps", o->steps, "control steps per run (default: the whole scenario, 520)")
      ->check(CLI::Range(1, 520));
  registry.push_back({sub, [o] { return Run(*o); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

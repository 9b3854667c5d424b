// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc run SCENARIO.yaml`: runs a formation scenario in the simulator (all sensors and
// estimators in the loop) and writes a run folder with CSV logs and summary.json.
#include <fmt/chrono.h>
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <thread>

#include "apps/fnmpc/commands.hpp"
#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/experiment/run_folder.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"
#include "fnmpc/onboard/formation_print.hpp"

namespace fnmpc::app {
namespace {

struct RunArgs {
  std::string scenario;
  std::string out;
  int runs = 1;
  int jobs = 1;
  int threads = 0;  // 0: the CPUs left per job
  long long seed = -1;
  double duration = -1.0;
  CLI::Option* duration_option = nullptr;
  bool quiet = false;
  bool overwrite = false;
  bool dry_run = false;
  std::string downwash;      // "", "on", "off"
  std::string reality;       // "", "on", "off"
  std::string compensation;  // "", or a name of formation::kCompensationChoice
  std::string shard;         // "", or I/N
  bool resume = false;
  std::string timing = "on";
};

/// Threads per run by default: the machine's CPUs shared by the jobs, at least 1.
int AutoThreads(int jobs) {
  const int cpus = static_cast<int>(std::thread::hardware_concurrency());
  return std::max(1, (cpus > 0 ? cpus : 1) / std::max(1, jobs));
}

int Run(const RunArgs& a) {
  config::ScenarioConfig sc = config::LoadScenarioFile(a.scenario);
  if (a.duration_option != nullptr && a.duration_option->count() > 0) {
    config::CheckDurationFlag(sc, a.duration);
    sc = experiment::Shortened(sc, a.duration);
  }
  if (!a.downwash.empty()) {
    sc.downwash = a.downwash == "on";
    sc.reality.wake = sc.downwash;  // the switch covers the reality wakes too
  }
  if (!a.reality.empty()) sc.reality.enabled = a.reality == "on";
  if (!a.compensation.empty()) {
    int level = 0;
    const std::string bad = formation::kCompensationChoice.Check(a.compensation, &level);
    if (!bad.empty()) throw std::invalid_argument("--compensation: " + bad);
    sc.compensation = static_cast<formation::Compensation>(level);
  }
  for (const std::string& w : sc.warnings) fmt::print(stderr, "fnmpc run: warning: {}\n", w);
  if (a.dry_run) {
    fmt::print("# {}: the vehicles as flown (fnmpc run --dry-run)\n{}", sc.name,
               onboard::VehiclesYaml(sc));
    return 0;
  }
  std::string dir = a.out;
  if (dir.empty()) {
    const std::time_t now = std::time(nullptr);
    dir = fmt::format("runs/{}-{:%Y%m%d-%H%M%S}", sc.name, fmt::localtime(now));
  }
  experiment::RunFolderOptions options;
  options.runs = a.runs;
  options.jobs = a.jobs;
  options.threads = a.threads > 0 ? a.threads : AutoThreads(a.jobs);
  options.seed = a.seed;
  options.progress = !a.quiet;
  options.scenario_file = a.scenario;
  options.stop = &g_stop_signal;
  options.timing = a.timing == "on";
  options.resume = a.resume;
  if (!a.shard.empty()) options.shard = experiment::ParseShard(a.shard);
  if (options.shard.index >= a.runs) {
    throw std::invalid_argument(fmt::format("--shard {}: shard {} has no run of --runs {}", a.shard,
                                            options.shard.index, a.runs));
  }
  if (a.resume) {
    experiment::CheckResumable(sc, options, dir);
  } else {
    experiment::PrepareRunFolder(dir, a.overwrite);
  }
  // Ctrl-C / SIGTERM: the current run finishes its physics step, writes what it has and the
  // folder is marked incomplete.
  StopSignalScope stop_scope;
  const nlohmann::json summary = experiment::RunFolder(sc, options, dir);
  stop_scope.Restore();
  bool sim_failed = false;
  for (const auto& r : summary.value("run_summaries", nlohmann::json::array())) {
    sim_failed = sim_failed || r.contains("error");
  }
  const std::size_t runs_done = summary.value("run_summaries", nlohmann::json::array()).size();
  fmt::print("{}\n", dir);
  if (g_stop_signal != 0) {
    fmt::print(stderr,
               "fnmpc run: interrupted (signal {}); {} of {} runs complete, {} marked "
               "\"complete\": false\n",
               static_cast<int>(g_stop_signal), runs_done == 0 ? 0 : runs_done - 1, a.runs,
               config::PathInside(dir, "summary.json"));
    return 128 + static_cast<int>(g_stop_signal);
  }
  if (sim_failed) return kExitSimulationError;
  const auto failures = summary.value("failures", nlohmann::json::array());
  for (const auto& f : failures) {
    fmt::print(stderr, "fnmpc run: FAILED {}: vehicle {}: {}\n", f.value("run", std::string()),
               f.value("vehicle", std::string()), f.value("reason", std::string()));
  }
  return failures.empty() ? 0 : kExitRunFailed;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* sub = app.add_subcommand("run", "Run a formation scenario in the simulator");
  sub->add_option("scenario", a->scenario,
                  "scenario YAML (config/scenarios/*.yaml, docs/scenarios.md)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("-o,--out", a->out, "run folder (default runs/<scenario>-<timestamp>)")
      ->check(CLI::Validator(
          [](std::string& s) { return s.empty() ? std::string("must not be empty") : ""; }, "DIR",
          "NonEmpty"));
  sub->add_flag("--overwrite", a->overwrite,
                "delete the files an earlier fnmpc run wrote in -o first (those its "
                ".fnmpc-manifest lists; nothing else; a folder without one is refused)");
  sub->add_option("--runs", a->runs, "number of runs with seeds seed, seed+1, ...")
      ->check(CLI::Range(1, 10000));
  sub->add_option("-j,--jobs", a->jobs,
                  "runs flown at the same time, one thread each; the run folder is the same as "
                  "with --jobs 1")
      ->check(CLI::Range(1, 256));
  sub->add_option("--threads", a->threads,
                  "threads per run for its vehicles' estimators and controllers, and from 16 "
                  "vehicles on for the world's sensors and aerodynamics (default: the "
                  "CPUs divided by --jobs; from 2 on, one more feeds the measurements while the "
                  "world steps); the run folder is the same whatever the count, timing columns "
                  "aside")
      ->check(CLI::Range(1, 256));
  sub->add_option("--seed", a->seed, "first noise seed (default: the scenario's)")
      ->check(CLI::Range(0LL, 1LL << 53));
  a->duration_option = sub->add_option(
      "--duration", a->duration,
      "shorten the scenario to this simulated time [s] (fewer legs, earlier landing; at most "
      "the scenario's duration)");
  sub->add_option("--downwash", a->downwash, "override the scenario's downwash switch")
      ->check(CLI::IsMember({"on", "off"}));
  sub->add_option("--reality", a->reality,
                  "override the scenario's reality switch (off: the ideal plant, the controllers' "
                  "own model; docs/simulator.md)")
      ->check(CLI::IsMember({"on", "off"}));
  sub->add_option("--compensation", a->compensation,
                  "override the scenario's controller.compensation: none (the reference work's "
                  "NMPC), observer (the estimated external acceleration in the prediction) or "
                  "wake (plus the neighbours' predicted wakes) or cooperative (plus the "
                  "neighbours' shared plans over the simulated link, block link:; "
                  "docs/scenarios.md)");
  sub->add_option("--shard", a->shard,
                  "I/N: fly only the runs r (0-based) with r % N == I, into run-(r+1); join the "
                  "N shard folders with `fnmpc merge` (docs/campaigns.md)");
  sub->add_flag("--resume", a->resume,
                "continue the run folder of an earlier, interrupted attempt of the same command: "
                "its complete runs are kept, the others flown")
      ->excludes(sub->get_option("--overwrite"));
  sub->add_option("--timing", a->timing,
                  "off: no wall-clock solver times (NaN in the CSVs, null in the summaries), so "
                  "the folder depends on the seeds alone, byte for byte")
      ->check(CLI::IsMember({"on", "off"}));
  sub->add_flag("-q,--quiet", a->quiet, "no progress output");
  sub->add_flag("--dry-run", a->dry_run,
                "check the scenario and print its vehicles (a generated formation expanded, "
                "each vehicle's graph depth) as a `vehicles:` list; fly nothing, write nothing");
  registry.push_back({sub, [a] { return Run(*a); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc tune SCENARIO... --trials N --held-out H...`: tunes the followers' NMPC weights with
// Optuna, each trial flown through `fnmpc campaign` (docs/tuning.md);
// tools/tune.py drives Optuna.
#include <csignal>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "apps/fnmpc/commands.hpp"
#include "apps/fnmpc/process.hpp"
#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/config/settings_doc.hpp"

namespace fnmpc::app {
namespace {

struct TuneArgs {
  std::vector<std::string> scenarios, held_out;
  int trials = 20;
  int seeds = 3;
  int held_out_seeds = 10;
  std::string executor = "local";
  std::string storage, study = "fnmpc-tune", out = "tune";
  double duration = 0.0;
  std::string script = std::string(FNMPC_SOURCE_DIR) + "/tools/tune.py";
  bool quiet = false;
};

/// The follower weights each scenario flies with, defaults included (the struct's own: a
/// scenario without `controller.weights.follower` flies NmpcWeights' defaults), as
/// {scenario: {key: YAML value}}; loading also checks every scenario before any flight.
nlohmann::json EffectiveFollowerWeights(const std::vector<std::string>& scenarios) {
  nlohmann::json all = nlohmann::json::object();
  for (const std::string& path : scenarios) {
    config::ScenarioConfig sc = config::LoadScenarioFile(path);
    config::SettingsDocWriter doc;
    sc.follower_weights.Serialize(&doc);
    nlohmann::json w = nlohmann::json::object();
    for (const config::SettingDoc& f : doc.fields()) w[f.key] = f.default_value;
    all[path] = w;
  }
  return all;
}

/// Marks an output folder of `fnmpc tune`.
const char* const kTuneMarker = ".fnmpc-tune";

/// Tune writes over its own files in OUT (tune.json, tuned-weights.yaml, trials/...; a rerun
/// continues the study there), so OUT must be new, empty or marked by an earlier tune; the
/// marker is written before anything else.
void ClaimTuneFolder(const std::string& out) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec)) {
    throw std::runtime_error(out + ": exists and is not a folder");
  }
  const std::string marker = config::PathInside(out, kTuneMarker);
  if (fs::is_directory(out, ec) && !fs::is_empty(out, ec) && !fs::is_regular_file(marker, ec)) {
    throw std::runtime_error(
        out + ": not empty and not an output folder of `fnmpc tune` (no " + kTuneMarker +
        "; tune writes over its own files there): choose another -o (a folder of an earlier "
        "fnmpc tune, which left no marker, must be deleted by hand)");
  }
  fs::create_directories(out, ec);
  if (ec) throw std::runtime_error(out + ": cannot create the folder: " + ec.message());
  config::WriteFileAtomically(marker, "fnmpc tune output folder (docs/tuning.md)\n");
}

int Tune(const TuneArgs& a) {
  std::vector<std::string> every = a.scenarios;
  every.insert(every.end(), a.held_out.begin(), a.held_out.end());
  ClaimTuneFolder(a.out);
  const std::string weights_file = config::PathInside(a.out, "effective-weights.json");
  config::WriteFileAtomically(weights_file, EffectiveFollowerWeights(every).dump(2) + "\n");
  std::error_code ec;
  const std::string self = std::filesystem::read_symlink("/proc/self/exe", ec).string();
  std::vector<std::string> argv = {"/usr/bin/python3",
                                   a.script,
                                   "--fnmpc",
                                   ec ? std::string("fnmpc") : self,
                                   "--trials",
                                   std::to_string(a.trials),
                                   "--seeds",
                                   std::to_string(a.seeds),
                                   "--held-out-seeds",
                                   std::to_string(a.held_out_seeds),
                                   "--executor",
                                   a.executor,
                                   "--study",
                                   a.study,
                                   "-o",
                                   a.out,
                                   "--effective-weights",
                                   weights_file};
  if (!a.storage.empty()) argv.insert(argv.end(), {"--storage", a.storage});
  if (a.duration > 0.0) argv.insert(argv.end(), {"--duration", std::to_string(a.duration)});
  if (a.quiet) argv.emplace_back("-q");
  argv.emplace_back("--held-out");
  argv.insert(argv.end(), a.held_out.begin(), a.held_out.end());
  argv.emplace_back("--");
  argv.insert(argv.end(), a.scenarios.begin(), a.scenarios.end());
  const int rc = RunProgram(argv, {"MPLBACKEND=Agg"});
  if (rc == 128 + SIGINT || rc == 128 + SIGTERM) throw Interrupted(rc, "tune interrupted");
  if (rc < 0) throw std::runtime_error(a.script + ": cannot start /usr/bin/python3");
  return rc;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<TuneArgs>();
  CLI::App* sub = app.add_subcommand(
      "tune", "Tune the followers' NMPC weights with Optuna, scored on held-out scenarios");
  sub->add_option("scenarios", a->scenarios, "tuning scenarios (YAML)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--held-out", a->held_out,
                  "scenarios scored with the defaults and the tuned weights after tuning only")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--trials", a->trials, "Optuna trials, trial 0 the defaults")
      ->check(CLI::Range(2, 10000))
      ->capture_default_str();
  sub->add_option("--seeds", a->seeds, "runs per tuning scenario and trial")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  sub->add_option("--held-out-seeds", a->held_out_seeds, "runs per held-out scenario")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  sub->add_option("--executor", a->executor, "how each evaluation's runs fly (fnmpc campaign)")
      ->check(CLI::IsMember({"local", "slurm", "dask"}))
      ->capture_default_str();
  sub->add_option("--storage", a->storage,
                  "Optuna storage URL (default sqlite:///OUT/tune.db; postgresql://... to share "
                  "one study between machines)");
  sub->add_option("--study", a->study, "study name in the storage")->capture_default_str();
  sub->add_option("--duration", a->duration, "fly every scenario this long [s] (0: their own)")
      ->check(FiniteIn(0.0, 1e6));
  sub->add_option("-o,--out", a->out, "output folder")->capture_default_str();
  sub->add_option("--script", a->script, "tuning driver")->check(CLI::ExistingFile);
  sub->add_flag("-q,--quiet", a->quiet, "no progress lines");
  registry.push_back({sub, [a] { return Tune(*a); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

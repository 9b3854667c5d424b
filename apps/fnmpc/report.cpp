// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc report RUN_DIR`: draws the plots and the HTML page of a run folder with
// tools/report.py (matplotlib, Agg backend) and writes the interactive 3-D replay
// replay.html with tools/replay.py (docs/replay.md).
#include <fmt/core.h>

#include <csignal>
#include <filesystem>
#include <memory>

#include "apps/fnmpc/commands.hpp"
#include "apps/fnmpc/process.hpp"

namespace fnmpc::app {
namespace {

struct ReportArgs {
  std::string dir;
  std::string script = std::string(FNMPC_SOURCE_DIR) + "/tools/report.py";
  std::string replay_script = std::string(FNMPC_SOURCE_DIR) + "/tools/replay.py";
  std::string replay_template = std::string(FNMPC_SOURCE_DIR) + "/web/replay/replay.html";
  std::string replay_bundle = FNMPC_REPLAY_BUNDLE;
  int replay_run = 1;
  bool replay_only = false;
};

/// Runs one report script; status 1 means the script refused the folder and said why in
/// one line.
int RunScript(const std::vector<std::string>& argv, const std::vector<std::string>& env) {
  // No shell: the folder name reaches the script verbatim.
  const int rc = RunProgram(argv, env);
  if (rc == 128 + SIGINT || rc == 128 + SIGTERM) throw Interrupted(rc, argv[1] + " interrupted");
  if (rc != 0 && rc != 1) fmt::print(stderr, "fnmpc report: {} failed (status {})\n", argv[1], rc);
  return rc == 0 ? kExitOk : kExitError;
}

int Report(const ReportArgs& a) {
  if (!a.replay_only &&
      RunScript({"/usr/bin/python3", a.script, a.dir}, {"MPLBACKEND=Agg"}) != kExitOk) {
    return kExitError;
  }
  if (!std::filesystem::is_regular_file(a.replay_bundle)) {
    fmt::print(stderr,
               "fnmpc report: replay.html not written: {} missing (build the fnmpc_replay "
               "target; it needs Node.js and npm)\n",
               a.replay_bundle);
    return kExitError;
  }
  return RunScript({"/usr/bin/python3", a.replay_script, a.dir, "--template", a.replay_template,
                    "--bundle", a.replay_bundle, "--run", std::to_string(a.replay_run)},
                   {});
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<ReportArgs>();
  CLI::App* sub =
      app.add_subcommand("report", "Plot a run folder (PNG + report.html) and write replay.html");
  sub->add_option("run_dir", a->dir, "run folder written by `fnmpc run`")
      ->required()
      ->check(CLI::ExistingDirectory);
  sub->add_option("--script", a->script, "report script")->check(CLI::ExistingFile);
  sub->add_option("--replay-run", a->replay_run, "run of the folder shown by replay.html (1-based)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--replay-bundle", a->replay_bundle,
                  "three.js viewer bundle (default: the build tree's, target fnmpc_replay)");
  sub->add_flag("--replay-only", a->replay_only, "write replay.html only (no PNG plots)");
  registry.push_back({sub, [a] { return Report(*a); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

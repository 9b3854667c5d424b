// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc report RUN_DIR`: draws the plots and the HTML page of a run folder with
// tools/report.py (matplotlib, Agg backend).
#include <fmt/core.h>

#include <csignal>
#include <filesystem>
#include <memory>

#include "apps/fnmpc/commands.hpp"
#include "apps/fnmpc/process.hpp"

namespace fnmpc::app {
namespace {

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto dir = std::make_shared<std::string>();
  auto script = std::make_shared<std::string>(std::string(FNMPC_SOURCE_DIR) + "/tools/report.py");
  CLI::App* sub = app.add_subcommand("report", "Plot a run folder (PNG + report.html)");
  sub->add_option("run_dir", *dir, "run folder written by `fnmpc run`")
      ->required()
      ->check(CLI::ExistingDirectory);
  sub->add_option("--script", *script, "report script")->check(CLI::ExistingFile);
  registry.push_back(
      {sub, [dir, script] {
         // No shell: the folder name reaches the script verbatim.
         const int rc = RunProgram({"/usr/bin/python3", *script, *dir}, {"MPLBACKEND=Agg"});
         if (rc == 128 + SIGINT || rc == 128 + SIGTERM) {
           throw Interrupted(rc, *script + " interrupted");
         }
         // Status 1: the script refused the folder and said why in one line.
         if (rc != 0 && rc != 1) {
           fmt::print(stderr, "fnmpc report: {} failed (status {})\n", *script, rc);
         }
         if (rc != 0) return kExitError;
         return kExitOk;
       }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

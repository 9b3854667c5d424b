// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc report RUN_DIR`: draws the plots and the HTML page of a run folder with
// tools/report.py (matplotlib, Agg backend).
#include <fmt/core.h>

#include <cstdlib>
#include <filesystem>
#include <memory>

#include "apps/fnmpc/commands.hpp"

namespace fnmpc::app {
namespace {

std::string Quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto dir = std::make_shared<std::string>();
  auto script = std::make_shared<std::string>(std::string(FNMPC_SOURCE_DIR) + "/tools/report.py");
  CLI::App* sub = app.add_subcommand("report", "Plot a run folder (PNG + report.html)");
  sub->add_option("run_dir", *dir, "run folder written by `fnmpc run`")
      ->required()
      ->check(CLI::ExistingDirectory);
  sub->add_option("--script", *script, "report script")->check(CLI::ExistingFile);
  registry.push_back({sub, [dir, script] {
                        const std::string cmd =
                            "MPLBACKEND=Agg /usr/bin/python3 " + Quote(*script) + " " + Quote(*dir);
                        const int rc = std::system(cmd.c_str());
                        if (rc != 0) {
                          fmt::print(stderr, "fnmpc report: {} failed ({})\n", *script, rc);
                          return 1;
                        }
                        return 0;
                      }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

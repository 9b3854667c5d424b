// SPDX-License-Identifier: BSD-3-Clause
// The fnmpc command-line tool: parses arguments and files, wires the layers, writes output.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "apps/fnmpc/commands.hpp"

#if defined(FNMPC_HAVE_SYSID)
#include <glog/logging.h>  // Ceres logs through glog
#endif

int main(int argc, char** argv) {
#if defined(FNMPC_HAVE_SYSID)
  // glog (Ceres' logger) complains "Logging before InitGoogleLogging" without this; its
  // messages go to stderr, warnings and above only, and no log files are written.
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = google::GLOG_WARNING;
  google::InitGoogleLogging(argv[0]);
#endif
  CLI::App app{"fnmpc: decentralized NMPC for multi-rotor formations"};
  app.require_subcommand(1);
  fnmpc::app::RegisterCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);  // prints the message (or the help)
    return rc == 0 ? fnmpc::app::kExitOk : fnmpc::app::kExitUsage;
  }
  try {
    return fnmpc::app::RunSelected(app);
  } catch (const fnmpc::app::Interrupted& e) {
    std::cerr << "fnmpc: " << e.what() << "\n";
    return e.code();
  } catch (const std::exception& e) {
    std::cerr << "fnmpc: error: " << e.what() << "\n";
    return fnmpc::app::kExitError;
  }
}

// SPDX-License-Identifier: BSD-3-Clause
// The fnmpc command-line tool: parses arguments and files, wires the layers, writes output.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "apps/fnmpc/commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{"fnmpc: decentralized NMPC for multi-rotor formations"};
  app.require_subcommand(1);
  fnmpc::app::RegisterCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    return fnmpc::app::RunSelected(app);
  } catch (const std::exception& e) {
    std::cerr << "fnmpc: error: " << e.what() << "\n";
    return 1;
  }
}

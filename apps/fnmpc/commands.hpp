// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <vector>

namespace fnmpc::app {

/// A subcommand registers itself with a CLI11 sub-app and the function that runs it.
struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

/// Every subcommand, registered by its own translation unit (bench.cpp, run.cpp, ...).
std::vector<Command>& Registry();
void RegisterCommands(CLI::App& app);
int RunSelected(CLI::App& app);

/// Each command file defines one of these registration functions.
using Registrar = void (*)(CLI::App&, std::vector<Command>&);
struct RegisterCommand {
  explicit RegisterCommand(Registrar r);
};

}  // namespace fnmpc::app

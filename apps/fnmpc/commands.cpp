// SPDX-License-Identifier: BSD-3-Clause
#include "apps/fnmpc/commands.hpp"

namespace fnmpc::app {

namespace {
std::vector<Registrar>& Registrars() {
  static std::vector<Registrar> r;
  return r;
}
}  // namespace

std::vector<Command>& Registry() {
  static std::vector<Command> c;
  return c;
}

RegisterCommand::RegisterCommand(Registrar r) { Registrars().push_back(r); }

void RegisterCommands(CLI::App& app) {
  for (Registrar r : Registrars()) r(app, Registry());
}

int RunSelected(CLI::App& app) {
  (void)app;
  for (const Command& c : Registry()) {
    if (c.app->parsed()) return c.run();
  }
  return 1;
}

}  // namespace fnmpc::app

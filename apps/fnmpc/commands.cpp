// SPDX-License-Identifier: BSD-3-Clause
#include "apps/fnmpc/commands.hpp"

namespace fnmpc::app {

volatile std::sig_atomic_t g_stop_signal = 0;

namespace {
extern "C" void OnStopSignal(int signo) { g_stop_signal = signo; }

std::vector<Registrar>& Registrars() {
  static std::vector<Registrar> r;
  return r;
}
}  // namespace

StopSignalScope::StopSignalScope() {
  g_stop_signal = 0;
  std::signal(SIGINT, OnStopSignal);
  std::signal(SIGTERM, OnStopSignal);
}

void StopSignalScope::Restore() {
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
}

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

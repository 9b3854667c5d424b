// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <CLI/CLI.hpp>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace fnmpc::app {

/// Exit codes of the fnmpc commands (docs/failure.md). A signal that stops a command gives
/// 128 + the signal number (130 for SIGINT, 143 for SIGTERM).
inline constexpr int kExitOk = 0;
inline constexpr int kExitError = 1;            ///< bad input, unwritable output, failed tool
inline constexpr int kExitUsage = 2;            ///< bad command line
inline constexpr int kExitRunFailed = 3;        ///< the run finished but a vehicle failed
inline constexpr int kExitSimulationError = 4;  ///< the simulator became unstable

/// CLI11 check for a number option: finite (no nan / inf) and within [lo, hi].
inline CLI::Validator FiniteIn(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v)) {
          return "must be a finite number, got '" + text + "'";
        }
        if (v < lo || v > hi) {
          return "must be in [" + CLI::detail::to_string(lo) + ", " + CLI::detail::to_string(hi) +
                 "], got " + text;
        }
        return "";
      },
      "FINITE", "FiniteIn");
}

/// Thrown when a signal stopped the command (or a helper program it ran); main() exits with
/// code().
class Interrupted : public std::runtime_error {
 public:
  Interrupted(int code, const std::string& what) : std::runtime_error(what), code_(code) {}
  [[nodiscard]] int code() const { return code_; }

 private:
  int code_;
};

/// The signal (SIGINT, SIGTERM) that asked the running command to stop, 0 while none came.
extern volatile std::sig_atomic_t g_stop_signal;

/// While it lives, SIGINT and SIGTERM set g_stop_signal (cleared on entry) instead of killing
/// the process, so the command can finish its step and write what it has; the default
/// actions after Restore() or the end of the scope.
class StopSignalScope {
 public:
  StopSignalScope();
  ~StopSignalScope() { Restore(); }
  void Restore();
  StopSignalScope(const StopSignalScope&) = delete;
  StopSignalScope& operator=(const StopSignalScope&) = delete;
};

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

// SPDX-License-Identifier: BSD-3-Clause
#include "apps/fnmpc/process.hpp"

#include <spawn.h>
#include <sys/wait.h>

#include <cerrno>
#include <csignal>
#include <cstring>

extern char** environ;  // NOLINT: POSIX

namespace fnmpc::app {
namespace {

volatile std::sig_atomic_t g_helper_stop_signal = 0;

extern "C" void OnSignalDuringHelper(int sig) { g_helper_stop_signal = sig; }

/// While a helper runs, SIGINT / SIGTERM are recorded instead of killing fnmpc at once (the
/// helper, in the same process group, gets Ctrl-C too and stops; a signal to fnmpc alone is
/// passed on to it), so fnmpc can report the interruption and clean up instead of either
/// dying without a word or, as std::system() did, ignoring Ctrl-C and reporting success; the
/// previous dispositions come back afterwards.
class StopSignalsRecorded {
 public:
  StopSignalsRecorded() {
    g_helper_stop_signal = 0;
    struct sigaction sa {};
    sa.sa_handler = OnSignalDuringHelper;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;  // no SA_RESTART: waitpid returns EINTR and is called again
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~StopSignalsRecorded() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StopSignalsRecorded(const StopSignalsRecorded&) = delete;
  StopSignalsRecorded& operator=(const StopSignalsRecorded&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

}  // namespace

int RunProgram(const std::vector<std::string>& argv, const std::vector<std::string>& extra_env) {
  if (argv.empty()) return -1;
  std::vector<std::string> env;
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
    const std::string entry(*e);
    const std::string name = entry.substr(0, entry.find('='));
    bool replaced = false;
    for (const auto& x : extra_env) replaced = replaced || x.substr(0, x.find('=')) == name;
    if (!replaced) env.push_back(entry);
  }
  env.insert(env.end(), extra_env.begin(), extra_env.end());
  std::vector<char*> args, envp;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  for (const auto& e : env) envp.push_back(const_cast<char*>(e.c_str()));
  envp.push_back(nullptr);
  // The helper starts with the default SIGINT / SIGTERM actions whatever fnmpc has set.
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGTERM);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF);
  const StopSignalsRecorded recorded;
  pid_t pid = 0;
  const int spawned = posix_spawnp(&pid, args[0], nullptr, &attr, args.data(), envp.data());
  posix_spawnattr_destroy(&attr);
  if (spawned != 0) return -1;
  int status = 0;
  bool forwarded = false;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return -1;
    if (g_helper_stop_signal != 0 && !forwarded) {
      // A signal sent to fnmpc alone (kill PID) stops the helper as well.
      kill(pid, g_helper_stop_signal);
      forwarded = true;
    }
  }
  // Ctrl-C counts even when the helper caught it and exited normally (Python may).
  if (g_helper_stop_signal != 0) return 128 + g_helper_stop_signal;
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

}  // namespace fnmpc::app

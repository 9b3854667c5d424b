// SPDX-License-Identifier: BSD-3-Clause
// Starting helper programs (the matplotlib report scripts) without a shell.
#pragma once

#include <string>
#include <vector>

namespace fnmpc::app {

/// Runs `argv[0]` (an absolute path or a name looked up in PATH) with the arguments
/// argv[1..] passed verbatim (no shell: quotes, `$()` and spaces in paths are not
/// interpreted), the current environment plus `extra_env` ("NAME=value" entries, which
/// replace variables of the same name), and waits for it. Returns the exit status, 128 +
/// signal number when it was killed or when fnmpc itself received SIGINT / SIGTERM while
/// waiting (the signal is passed on to the helper), or -1 when it could not be started.
int RunProgram(const std::vector<std::string>& argv,
               const std::vector<std::string>& extra_env = {});

}  // namespace fnmpc::app

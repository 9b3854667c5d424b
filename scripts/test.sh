#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The whole test suite on a fresh machine: installs the Debian packages (ROS 1 included),
# builds with AddressSanitizer + UndefinedBehaviorSanitizer and runs every test with
# ctest (install_and_examples installs that build and runs examples/ against it), runs the
# solver's unit tests again in a Debug build with assertions on, then builds the ROS package
# and runs its rostests (scripts/test-ros.sh).
#   scripts/test.sh [extra ctest arguments for the library suite]
set -euo pipefail
cd "$(dirname "$0")/.."
# Debian's ROS and matplotlib need the system python, not a pyenv one first on PATH.
export PATH=/usr/bin:$PATH
bash scripts/install-deps.sh --with-ros
build=${FNMPC_TEST_BUILD_DIR:-build-test}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFNMPC_SANITIZE=ON -DFNMPC_BUILD_BENCH=OFF
cmake --build "$build" -j"$(nproc)"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
(cd "$build" && ctest --output-on-failure -j"$(nproc)" "$@")
unset ASAN_OPTIONS UBSAN_OPTIONS
# The solver's unit tests once more in a Debug build: FNMPC_ASSERT and Eigen's own checks
# (index ranges, sizes, aliasing) are compiled out of the build above (NDEBUG). Only the
# core, qp, ocp and solver-contract tests, to keep it short; tests of executables not built
# here show up as *_NOT_BUILT in ctest and are excluded, and so is the install test (run
# above); the Python and replay tests are not configured.
debug=${FNMPC_DEBUG_BUILD_DIR:-build-debug}
cmake -S . -B "$debug" -DCMAKE_BUILD_TYPE=Debug -DFNMPC_BUILD_BENCH=OFF -DFNMPC_WITH_MUJOCO=OFF \
  -DFNMPC_WITH_IPOPT=OFF -DFNMPC_WITH_PYTHON=OFF -DFNMPC_WITH_REPLAY=OFF
cmake --build "$debug" -j"$(nproc)" --target core_test qp_test ocp_test problem_contract_test
(cd "$debug" && ctest --output-on-failure -j"$(nproc)" -E "_NOT_BUILT|install_and_examples")
bash scripts/test-ros.sh

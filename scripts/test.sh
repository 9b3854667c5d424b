#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The whole test suite on a fresh machine: installs the Debian packages (ROS 1 included),
# builds with AddressSanitizer + UndefinedBehaviorSanitizer, the ROS package in the same
# tree, and runs every test with ctest (the rostests and install_and_examples, which
# installs that build and runs examples/ against it, included), then runs the solver's unit
# tests again in a Debug build with assertions on.
#   scripts/test.sh [extra ctest arguments for the library suite]
set -euo pipefail
cd "$(dirname "$0")/.."
# Debian's ROS and matplotlib need the system python, not a pyenv one first on PATH.
export PATH=/usr/bin:$PATH
bash scripts/install-deps.sh --with-ros
build=${FNMPC_TEST_BUILD_DIR:-build-test}
# -O1 -g1: the sanitizers' recommended optimisation and line tables only (enough for their
# stack traces); the heavy solver translation units compile in about half the time of
# -O2 -g (docs/benchmarks.md "Test suite"). Ninja keeps both cores busy to the last link.
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DFNMPC_SANITIZE=ON \
  -DFNMPC_BUILD_BENCH=OFF -DFNMPC_WITH_ROS=ON
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
cmake -S . -B "$debug" -G Ninja -DCMAKE_BUILD_TYPE=Debug -DFNMPC_BUILD_BENCH=OFF -DFNMPC_WITH_MUJOCO=OFF \
  -DFNMPC_WITH_IPOPT=OFF -DFNMPC_WITH_PYTHON=OFF -DFNMPC_WITH_REPLAY=OFF
cmake --build "$debug" -j"$(nproc)" --target core_test qp_test ocp_test problem_contract_test
(cd "$debug" && ctest --output-on-failure -j"$(nproc)" -E "_NOT_BUILT|install_and_examples")

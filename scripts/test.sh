#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The whole test suite on a fresh machine: installs the Debian packages (ROS 1 included),
# builds with AddressSanitizer + UndefinedBehaviorSanitizer and runs every test with
# ctest, then builds the ROS package and runs its rostests (scripts/test-ros.sh).
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
bash scripts/test-ros.sh

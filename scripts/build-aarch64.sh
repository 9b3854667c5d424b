#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Cross-builds the onboard parts of fnmpc for 64-bit ARM Linux (aarch64) from a fresh Debian
# bookworm machine (docs/onboard.md): installs the cross toolchain, qemu-user and the arm64
# libraries (scripts/install-deps.sh --with-aarch64), configures with
# cmake/toolchain-aarch64-linux-gnu.cmake and FNMPC_ONBOARD_ONLY=ON (core..formation,
# estimation, the MAVLink codec and autopilot link, config, the fnmpc executable; no MuJoCo),
# builds, and with --test runs the onboard tests under qemu-aarch64 with ctest.
#   scripts/build-aarch64.sh [--test] [--no-install] [extra ctest arguments after --]
# Environment:
#   FNMPC_AARCH64_BUILD_DIR   build directory (default build-aarch64)
#   FNMPC_AARCH64_BUILD_TYPE  CMake build type (default Release: what flies, and what the
#                             instruction counts of docs/onboard.md are measured on)
#   FNMPC_AARCH64_CXX_FLAGS   flags of that build type (default: CMake's)
#   FNMPC_AARCH64_ARCH        FNMPC_ARCH of the build (default none: generic armv8-a, runs on
#                             any 64-bit ARM board; e.g. armv8-a+crc for a Pi 4's Cortex-A72)
#   FNMPC_AARCH64_JOBS        parallel jobs (default: the number of cores)
set -euo pipefail
cd "$(dirname "$0")/.."
run_tests=0
install=1
ctest_args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --test) run_tests=1 ;;
    --no-install) install=0 ;;
    --) shift; ctest_args=("$@"); break ;;
    *) echo "build-aarch64: unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
if [[ $install -eq 1 ]]; then bash scripts/install-deps.sh --with-aarch64; fi
build=${FNMPC_AARCH64_BUILD_DIR:-build-aarch64}
type=${FNMPC_AARCH64_BUILD_TYPE:-Release}
jobs=${FNMPC_AARCH64_JOBS:-$(nproc)}
flags=()
if [[ -n "${FNMPC_AARCH64_CXX_FLAGS:-}" ]]; then
  flags=("-DCMAKE_CXX_FLAGS_$(echo "$type" | tr '[:lower:]' '[:upper:]')=${FNMPC_AARCH64_CXX_FLAGS}")
fi
# yaml-cpp's arm64 CMake files: libyaml-cpp-dev:arm64 cannot be installed beside the build
# machine's libyaml-cpp-dev (not Multi-Arch: same), so it is unpacked here; its library is the
# installed libyaml-cpp0.7:arm64 (the same files, unpacked too so the CMake files find them).
mkdir -p "$build"
build=$(cd "$build" && pwd)
deps="$build/arm64-deps"
mkdir -p "$deps"
if [[ ! -f "$deps/usr/lib/aarch64-linux-gnu/cmake/yaml-cpp/yaml-cpp-config.cmake" ]]; then
  tmp=$(mktemp -d)
  (cd "$tmp" && apt-get download -q libyaml-cpp-dev:arm64 libyaml-cpp0.7:arm64)
  for deb in "$tmp"/*.deb; do dpkg-deb -x "$deb" "$deps"; done
  rm -rf "$tmp"
fi
cmake -S . -B "$build" -G Ninja \
  -DCMAKE_TOOLCHAIN_FILE="$PWD/cmake/toolchain-aarch64-linux-gnu.cmake" \
  -Dyaml-cpp_DIR="$deps/usr/lib/aarch64-linux-gnu/cmake/yaml-cpp" \
  -DCMAKE_BUILD_TYPE="$type" "${flags[@]}" -DFNMPC_ONBOARD_ONLY=ON \
  -DFNMPC_ARCH="${FNMPC_AARCH64_ARCH:-none}"
cmake --build "$build" -j"$jobs"
file "$build/apps/fnmpc/fnmpc" | grep -q "ARM aarch64" || {
  echo "build-aarch64: $build/apps/fnmpc/fnmpc is not an aarch64 executable" >&2
  exit 1
}
if [[ $run_tests -eq 1 ]]; then
  # ctest runs every test binary through qemu-aarch64 (CMAKE_CROSSCOMPILING_EMULATOR).
  (cd "$build" && ctest --output-on-failure -j"$jobs" "${ctest_args[@]}")
fi

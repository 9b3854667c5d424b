# SPDX-License-Identifier: BSD-3-Clause
# Cross toolchain for 64-bit ARM Linux (aarch64, e.g. a Raspberry Pi 4 running a 64-bit
# Debian): Debian's g++-aarch64-linux-gnu against the arm64 multiarch libraries in
# /usr/lib/aarch64-linux-gnu (libyaml-cpp-dev:arm64, libfmt-dev:arm64, ...; Eigen, CLI11 and
# nlohmann-json are header-only and come from the build machine's /usr/include). Executables
# built here (tests, gtest discovery) run under qemu-aarch64. scripts/install-deps.sh
# --with-aarch64 installs all of it; scripts/build-aarch64.sh uses this file. docs/onboard.md.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
# find_package and find_library look in lib/aarch64-linux-gnu (never the build machine's
# lib/x86_64-linux-gnu).
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
# GCC's notes that the passing of some aggregates changed in GCC 10.1 (-Wpsabi) concern only
# linking with objects of GCC 9 or older; everything here is built by one compiler.
set(CMAKE_CXX_FLAGS_INIT "-Wno-psabi")
find_program(FNMPC_QEMU_AARCH64 qemu-aarch64)
if(NOT FNMPC_QEMU_AARCH64)
  find_program(FNMPC_QEMU_AARCH64 qemu-aarch64-static)
endif()
if(FNMPC_QEMU_AARCH64)
  # The arm64 dynamic loader and libraries of the multiarch packages are found without -L.
  set(CMAKE_CROSSCOMPILING_EMULATOR ${FNMPC_QEMU_AARCH64})
endif()

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Eigen, with the two settings that decide the binary interface of fnmpc's Eigen objects
// checked. Every fnmpc header includes Eigen through this one.
//
// Why: fnmpc may be compiled for a wider instruction set (FNMPC_ARCH, AVX2) than a program
// that links it. Eigen derives from the instruction set both the alignment of fixed-size
// objects and its heap allocator: with AVX and the default settings it over-allocates and
// stores the original pointer in front of each block, without AVX it calls plain malloc. A
// matrix allocated inside the library and freed in the program (the destructor of
// qp::DenseQp is inline) then aborts with "double free or corruption". Pinning both
// settings makes every translation unit agree whatever its instruction set (and with or
// without AddressSanitizer, which also changes Eigen's choice):
//   EIGEN_MAX_ALIGN_BYTES=16        fixed-size objects aligned as with SSE2, the x86-64
//                                   baseline, also the layout of Debian's prebuilt users
//                                   of Eigen (Ceres, ROS);
//   EIGEN_MALLOC_ALREADY_ALIGNED=1  heap blocks come from plain malloc, which glibc aligns
//                                   to 16 bytes on 64-bit targets, enough for the above.
// The fnmpc:: CMake targets carry both as interface compile definitions
// (fnmpc/core/CMakeLists.txt); this check refuses a translation unit built without them.
#include <Eigen/Core>

static_assert(EIGEN_MAX_ALIGN_BYTES == 16,
              "fnmpc: compile with -DEIGEN_MAX_ALIGN_BYTES=16 (link the fnmpc:: CMake targets, "
              "which set it); other values change the layout of fnmpc's Eigen members");
static_assert(EIGEN_MALLOC_ALREADY_ALIGNED == 1,
              "fnmpc: compile with -DEIGEN_MALLOC_ALREADY_ALIGNED=1 (link the fnmpc:: CMake "
              "targets, which set it); otherwise Eigen objects allocated in the library are "
              "freed with a different allocator in your program");

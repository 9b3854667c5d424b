// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Force-included (-include) into the no-allocation test binary, before any Eigen header:
// every failed eigen_assert, including Eigen's "heap allocation is forbidden" check of
// EIGEN_RUNTIME_NO_MALLOC, is counted instead of aborting, so the test can report it.

#include <atomic>

namespace fnmpc::qp::testing {
/// Number of failed eigen_assert checks since program start.
inline std::atomic<int> g_eigen_assert_failures{0};
}  // namespace fnmpc::qp::testing

#define eigen_assert(x)                                                   \
  do {                                                                    \
    if (!(x)) ::fnmpc::qp::testing::g_eigen_assert_failures.fetch_add(1); \
  } while (false)

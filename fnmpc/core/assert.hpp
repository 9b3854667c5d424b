// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <stdexcept>
#include <string>

/// Assertion macros for internal invariants (Drake's DRAKE_ASSERT / DRAKE_DEMAND):
///   FNMPC_DEMAND(condition)  always checked;
///   FNMPC_ASSERT(condition)  checked when NDEBUG is not defined (Debug builds) or when
///                            FNMPC_ENABLE_ASSERTS is; compiled out otherwise (the
///                            condition is not evaluated), so it may sit in hot loops.
/// A failed check throws fnmpc::AssertionError naming the condition, file and line: it marks
/// a bug in fnmpc (or a broken precondition the caller was told about), not bad input, which
/// public entry points reject with std::invalid_argument / std::out_of_range before use.
/// Library code never prints; an uncaught AssertionError ends the program with its message.
namespace fnmpc {

class AssertionError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

namespace internal {
[[noreturn]] inline void AssertionFailed(const char* condition, const char* file, int line) {
  throw AssertionError(std::string("fnmpc assertion failed: ") + condition + " at " + file + ":" +
                       std::to_string(line));
}
}  // namespace internal

}  // namespace fnmpc

#define FNMPC_DEMAND(condition)                                                           \
  do {                                                                                    \
    if (!(condition)) ::fnmpc::internal::AssertionFailed(#condition, __FILE__, __LINE__); \
  } while (false)

#if !defined(NDEBUG) || defined(FNMPC_ENABLE_ASSERTS)
#define FNMPC_ASSERT_ARMED 1
#define FNMPC_ASSERT(condition) FNMPC_DEMAND(condition)
#else
#define FNMPC_ASSERT_ARMED 0
#define FNMPC_ASSERT(condition) \
  do {                          \
  } while (false)
#endif

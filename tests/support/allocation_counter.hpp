// SPDX-License-Identifier: BSD-3-Clause
#pragma once
// Replaces the global allocation functions of the test binary that includes this header
// (from exactly one translation unit) so that tests can count operator new calls: the
// "no heap allocation after construction" rule. The replacements use malloc/free, which
// AddressSanitizer intercepts, so the count also works in the sanitizer build.

#include <atomic>
#include <cstdlib>
#include <new>

namespace fnmpc::testing {

/// Counts the global operator new calls made while a counter is alive.
class AllocationCounter {
 public:
  AllocationCounter() {
    Calls().store(0);
    Counting().store(true);
  }
  ~AllocationCounter() { Counting().store(false); }
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;

  /// Calls of operator new since construction.
  [[nodiscard]] long count() const { return Calls().load(); }

  static std::atomic<long>& Calls() {
    static std::atomic<long> calls{0};
    return calls;
  }
  static std::atomic<bool>& Counting() {
    static std::atomic<bool> counting{false};
    return counting;
  }
};

}  // namespace fnmpc::testing

// Not inlined: GCC 12 inlines malloc/free into the callers and then reports new/free
// mismatches (-Wmismatched-new-delete) that are none, since these pairs match.
[[gnu::noinline]] void* operator new(std::size_t n) {
  if (fnmpc::testing::AllocationCounter::Counting().load()) {
    fnmpc::testing::AllocationCounter::Calls().fetch_add(1);
  }
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
[[gnu::noinline]] void* operator new[](std::size_t n) { return operator new(n); }
[[gnu::noinline]] void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  return std::malloc(n == 0 ? 1 : n);
}
[[gnu::noinline]] void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  return std::malloc(n == 0 ? 1 : n);
}
[[gnu::noinline]] void operator delete(void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete[](void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

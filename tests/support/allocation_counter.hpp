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

namespace detail {
inline std::atomic<long> g_allocations{0};
inline std::atomic<bool> g_counting{false};
}  // namespace detail

/// Runs f() and returns how many times it called the global operator new.
template <class F>
long CountAllocations(F&& f) {
  detail::g_allocations.store(0);
  detail::g_counting.store(true);
  f();
  detail::g_counting.store(false);
  return detail::g_allocations.load();
}

}  // namespace fnmpc::testing

// Not inlined: GCC 12 inlines malloc/free into the callers and then reports new/free
// mismatches (-Wmismatched-new-delete) that are none, since these pairs match.
[[gnu::noinline]] void* operator new(std::size_t n) {
  if (fnmpc::testing::detail::g_counting.load()) fnmpc::testing::detail::g_allocations.fetch_add(1);
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

// SPDX-License-Identifier: BSD-3-Clause
#pragma once
// Counts calls of the C allocation functions (malloc, calloc, realloc, aligned_alloc,
// posix_memalign) made from the code linked into the test binary: the test links with
// -Wl,--wrap=<function> for each (fnmpc_add_malloc_counter in tests/CMakeLists.txt), so the
// linker routes those calls to the __wrap_ functions below. Unlike a replaced operator new,
// this also sees Eigen's aligned_malloc and any direct malloc. The global operator new is the
// replacement of allocation_counter.hpp, which calls malloc from this binary, so every new
// (std::vector, std::string, ...) is counted here too; the library's own operator new in
// libstdc++ calls malloc inside the shared library, where --wrap does not reach. Include from
// exactly one translation unit of the test binary.

#include <atomic>
#include <cstddef>

#include "tests/support/allocation_counter.hpp"

extern "C" {
void* __real_malloc(std::size_t n);
void* __real_calloc(std::size_t n, std::size_t size);
void* __real_realloc(void* p, std::size_t n);
void* __real_aligned_alloc(std::size_t alignment, std::size_t n);
int __real_posix_memalign(void** p, std::size_t alignment, std::size_t n);
}

namespace fnmpc::testing {

namespace malloc_detail {
inline std::atomic<long> g_calls{0};
inline std::atomic<bool> g_counting{false};
inline void Count() {
  if (g_counting.load(std::memory_order_relaxed)) g_calls.fetch_add(1);
}
}  // namespace malloc_detail

/// Runs f() and returns how many C allocation calls it made.
template <class F>
long CountMallocs(F&& f) {
  malloc_detail::g_calls.store(0);
  malloc_detail::g_counting.store(true);
  f();
  malloc_detail::g_counting.store(false);
  return malloc_detail::g_calls.load();
}

}  // namespace fnmpc::testing

extern "C" {
void* __wrap_malloc(std::size_t n) {
  fnmpc::testing::malloc_detail::Count();
  return __real_malloc(n);
}
void* __wrap_calloc(std::size_t n, std::size_t size) {
  fnmpc::testing::malloc_detail::Count();
  return __real_calloc(n, size);
}
void* __wrap_realloc(void* p, std::size_t n) {
  fnmpc::testing::malloc_detail::Count();
  return __real_realloc(p, n);
}
void* __wrap_aligned_alloc(std::size_t alignment, std::size_t n) {
  fnmpc::testing::malloc_detail::Count();
  return __real_aligned_alloc(alignment, n);
}
int __wrap_posix_memalign(void** p, std::size_t alignment, std::size_t n) {
  fnmpc::testing::malloc_detail::Count();
  return __real_posix_memalign(p, alignment, n);
}
}

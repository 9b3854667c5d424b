// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/measurement_feeder.hpp"

#include <algorithm>
#include <bit>

namespace fnmpc::experiment {
namespace {

// A waiting thread spins this many times before it sleeps (the feeding thread) or yields
// (TakeRest): the world's next step, and with it the next measurement, is tens of
// microseconds away.
constexpr int kSpins = 2000;

inline void CpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

}  // namespace

MeasurementFeeder::MeasurementFeeder(Sink sink, std::size_t capacity)
    : sink_(std::move(sink)),
      ring_(std::bit_ceil(std::max<std::size_t>(capacity, 2))),
      mask_(static_cast<std::uint32_t>(ring_.size() - 1)),
      thread_([this] { Consume(); }) {}

MeasurementFeeder::~MeasurementFeeder() {
  // quit_ before the head moves: the thread reads quit_ after every head it sees.
  quit_.store(true);
  head_.fetch_add(1);
  head_.notify_one();
  thread_.join();
}

void MeasurementFeeder::Push(const Measurement& m) {
  const std::uint32_t h = head_.load(std::memory_order_relaxed);
  // Full, or measurements already aside (they come after every one in the ring): aside,
  // fed by the caller after TakeRest rather than by a thread the producer would wait for.
  if (!aside_.empty() || h - done_.load(std::memory_order_acquire) > mask_) {
    aside_.push_back(m);
    return;
  }
  ring_[h & mask_] = m;
  head_.store(h + 1, std::memory_order_release);
  head_.notify_one();  // no system call while the thread spins
}

void MeasurementFeeder::WaitUntilDone(std::uint32_t n) const {
  for (int spin = 0; done_.load(std::memory_order_acquire) != n; ++spin) {
    if (spin < kSpins) {
      CpuRelax();
    } else {
      std::this_thread::yield();
    }
  }
}

void MeasurementFeeder::Consume() {
  int idle = 0;
  for (;;) {
    // claimed_ before head_: TakeRest moves claimed_ only up to a head it pushed, so n <= h.
    std::uint32_t n = claimed_.load();
    const std::uint32_t h = head_.load(std::memory_order_acquire);
    if (quit_.load()) return;
    if (n == h) {
      if (++idle < kSpins) {
        CpuRelax();
      } else {
        head_.wait(h);
        idle = 0;
      }
      continue;
    }
    idle = 0;
    // Claim measurement n, unless TakeRest took it (and all after it) first.
    if (!claimed_.compare_exchange_strong(n, n + 1)) continue;
    try {
      sink_(ring_[n & mask_]);
    } catch (...) {
      if (!error_) error_ = std::current_exception();
    }
    done_.store(n + 1, std::memory_order_release);
  }
}

}  // namespace fnmpc::experiment

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <functional>
#include <thread>
#include <utility>
#include <vector>

#include "fnmpc/core/sensors.hpp"

namespace fnmpc::experiment {

/// Processes measurements on a thread of its own, in the order they were pushed, while the
/// pushing thread goes on (it steps the world). One producer, one consumer, a fixed ring;
/// Push never waits: once the ring is full, measurements are kept aside (in order) until
/// TakeRest. TakeRest stops the feeding between two measurements and hands the caller every
/// measurement not yet processed, in push order; until the next Push the consumer touches
/// nothing, so the caller may then call whatever the sink calls (and split the rest between
/// threads, e.g. by vehicle, as long as each vehicle's measurements keep their order). The
/// sink's first exception is rethrown by TakeRest.
class MeasurementFeeder {
 public:
  using Sink = std::function<void(const Measurement&)>;

  /// capacity: ring length, rounded up to a power of two (>= 2).
  explicit MeasurementFeeder(Sink sink, std::size_t capacity = 8192);
  /// Stops the thread; measurements not yet processed are dropped.
  ~MeasurementFeeder();
  MeasurementFeeder(const MeasurementFeeder&) = delete;
  MeasurementFeeder& operator=(const MeasurementFeeder&) = delete;

  void Push(const Measurement& m);

  /// Calls rest(m) for each measurement the thread has not processed, in push order; they
  /// count as processed afterwards. Returns how many there were.
  template <class F>
  std::uint32_t TakeRest(F&& rest) {
    const std::uint32_t h = head_.load(std::memory_order_relaxed);
    const std::uint32_t from = claimed_.exchange(h);
    WaitUntilDone(from);  // the measurement the thread may be processing
    for (std::uint32_t n = from; n != h; ++n) rest(ring_[n & mask_]);
    for (const Measurement& m : aside_) rest(m);
    done_.store(h, std::memory_order_release);
    const auto count = static_cast<std::uint32_t>(h - from + aside_.size());
    aside_.clear();
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
    return count;
  }

  /// Measurements that went through the ring so far (the ones kept aside not counted).
  [[nodiscard]] std::uint32_t ringed() const { return head_.load(std::memory_order_relaxed); }

 private:
  void Consume();
  void WaitUntilDone(std::uint32_t n) const;

  Sink sink_;
  std::vector<Measurement> ring_;
  std::uint32_t mask_;
  // Counters modulo 2^32 (measurement n lives in ring slot n & mask_): pushed (head_, by the
  // producer), handed out (claimed_: the thread claims one at a time, TakeRest all the rest)
  // and finished (done_: every measurement before it was processed or taken).
  alignas(64) std::atomic<std::uint32_t> head_{0};
  alignas(64) std::atomic<std::uint32_t> claimed_{0};
  alignas(64) std::atomic<std::uint32_t> done_{0};
  std::atomic<bool> quit_{false};
  std::exception_ptr error_;        // written by the thread before it publishes done_
  std::vector<Measurement> aside_;  // pushed while the ring was full (producer only)
  std::thread thread_;
};

}  // namespace fnmpc::experiment

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace fnmpc::experiment {

/// A fixed set of worker threads, created once, that run f(i) for i = 0 .. n-1 (ForEach):
/// the calling thread takes part, the indices are handed out one at a time (in any order, on
/// any thread), ForEach returns when all are done. With one thread nothing is started and
/// ForEach is a plain loop. f must only touch what index i owns for the result not to
/// depend on the thread count. The first exception thrown by f is rethrown by ForEach
/// (after every index was handed out).
class WorkerPool {
 public:
  /// threads >= 1: the calling thread plus threads - 1 workers.
  explicit WorkerPool(int threads) {
    for (int k = 1; k < threads; ++k) workers_.emplace_back([this] { Work(); });
  }
  ~WorkerPool() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      quit_ = true;
    }
    wake_.notify_all();
    for (std::thread& w : workers_) w.join();
  }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  /// Threads taking part (the caller included).
  [[nodiscard]] int threads() const { return static_cast<int>(workers_.size()) + 1; }

  template <class F>
  void ForEach(int n, F&& f) {
    if (workers_.empty() || n <= 1) {
      for (int i = 0; i < n; ++i) f(i);
      return;
    }
    using Fn = std::remove_reference_t<F>;  // may be const
    job_ = [](const void* ctx, int i) { (*static_cast<Fn*>(const_cast<void*>(ctx)))(i); };
    ctx_ = &f;
    n_ = n;
    next_.store(0);
    error_ = nullptr;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      busy_ = static_cast<int>(workers_.size());
      ++generation_;
    }
    wake_.notify_all();
    Drain();
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return busy_ == 0; });
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void Drain() {
    for (int i = next_.fetch_add(1); i < n_; i = next_.fetch_add(1)) {
      try {
        job_(ctx_, i);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
      }
    }
  }
  void Work() {
    std::uint64_t seen = 0;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return quit_ || generation_ != seen; });
        if (quit_) return;
        seen = generation_;
      }
      Drain();
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        --busy_;
      }
      done_.notify_one();
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::uint64_t generation_ = 0;
  int busy_ = 0;
  bool quit_ = false;
  // The current ForEach: written before the generation changes (under the mutex), read by
  // the workers after they see it change.
  void (*job_)(const void*, int) = nullptr;
  const void* ctx_ = nullptr;
  int n_ = 0;
  std::atomic<int> next_{0};
  std::exception_ptr error_;
};

}  // namespace fnmpc::experiment

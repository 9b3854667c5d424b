// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <vector>

#include "fnmpc/estimation/ekf_types.hpp"

namespace fnmpc::estimation {

/// Entries a ReplayBuffer with window `max_lag` [s] needs for event streams of the given
/// rates [Hz] (regularly stamped; a rate <= 0 is a stream that is off): a stream at rate r
/// has at most floor(max_lag r) + 1 stamps in a window of max_lag, taken here with a 25 %
/// margin on r (a stream a little faster than configured); one more entry holds the
/// snapshot before the window (Prune keeps it). Sized like this, in-order and late events
/// within the window never evict one another (ReplayBuffer::overflows stays 0).
inline int ReplayCapacity(double max_lag, std::initializer_list<double> rates_hz) {
  constexpr double kRateMargin = 1.25;
  int n = 1;
  for (const double r : rates_hz) {
    if (r > 0.0) n += static_cast<int>(std::floor(kRateMargin * max_lag * r)) + 1;
  }
  return std::max(n, 2);
}

/// Time-ordered ring buffer of recent events (measurements, inputs) and of the filter
/// state *before* each event, used to fuse late and out-of-order events exactly.
///
/// Events are ordered by (stamp, order); equal keys keep their arrival order. An event
/// newer than every buffered one is applied directly. An older one restores the snapshot
/// stored at its insertion point, is applied, and every later event is re-applied
/// ("replay"), so the result equals in-order delivery bit for bit. Events older than
/// `newest stamp - max_lag` are rejected (kRejectedTooOld). Entries older than the lag are
/// pruned; when the fixed capacity is reached the oldest entry is evicted (counted).
///
/// `Event` needs `double stamp` and `int order`; `State` needs `double time` (the stamp of
/// the last applied event, NaN before the first one). Storage is allocated once in the
/// constructor; Submit() performs no heap allocation.
template <class Event, class State>
class ReplayBuffer {
 public:
  /// One buffered event with the state before it and the status of its last application.
  struct Slot {
    Event event{};
    State before{};
    EkfStatus status = EkfStatus::kAccepted;
  };

  /// capacity: number of events kept (>= 2); max_lag: replay window [s] (>= 0).
  ReplayBuffer(int capacity, double max_lag)
      : slots_(static_cast<std::size_t>(capacity)), capacity_(capacity), max_lag_(max_lag) {}

  /// Inserts `event` and applies it to `state`, replaying later events when needed.
  /// apply(const Event&, State*) -> EkfStatus updates the state with one event;
  /// recount(const Event&, EkfStatus old, EkfStatus now) is called for each replayed event
  /// whose outcome changed. Returns the status of `event`.
  template <class Apply, class Recount>
  EkfStatus Submit(const Event& event, State* state, Apply&& apply, Recount&& recount) {
    if (size_ > 0 && event.stamp < newest_ - max_lag_) return EkfStatus::kRejectedTooOld;
    int pos = UpperBound(event);
    if (pos < size_ && size_ == capacity_) {
      // Full and inserting in the middle: evict the oldest first.
      PopFront();
      ++overflows_;
      --pos;
    }
    if (pos < 0) return EkfStatus::kRejectedTooOld;
    const State& start = pos < size_ ? At(pos).before : *state;
    if (std::isfinite(start.time) && event.stamp < start.time) return EkfStatus::kRejectedTooOld;
    if (pos == size_) {
      if (size_ == capacity_) {
        PopFront();
        ++overflows_;
        --pos;
      }
      Slot& s = At(size_++);
      s.event = event;
      s.before = *state;
      s.status = apply(event, state);
      newest_ = size_ == 1 ? event.stamp : std::max(newest_, event.stamp);
      Prune();
      return s.status;
    }
    // Out of order: restore, shift the tail right by one, apply and replay.
    ++replays_;
    *state = At(pos).before;
    ++size_;
    for (int i = size_ - 1; i > pos; --i) At(i) = At(i - 1);
    Slot& s = At(pos);
    s.event = event;
    s.before = *state;
    s.status = apply(event, state);
    const EkfStatus result = s.status;
    for (int i = pos + 1; i < size_; ++i) {
      Slot& r = At(i);
      r.before = *state;
      const EkfStatus now = apply(r.event, state);
      if (now != r.status) {
        recount(r.event, r.status, now);
        r.status = now;
      }
    }
    Prune();
    return result;
  }

  /// Forgets every event (e.g. after a reset of the filter).
  void Clear() {
    size_ = 0;
    head_ = 0;
    newest_ = kNaN;
  }

  /// Number of buffered events.
  [[nodiscard]] int size() const { return size_; }
  /// Fixed capacity.
  [[nodiscard]] int capacity() const { return capacity_; }
  /// Newest buffered stamp [s] (NaN when empty).
  [[nodiscard]] double newest_stamp() const { return newest_; }
  /// Number of out-of-order insertions so far.
  [[nodiscard]] std::int64_t replays() const { return replays_; }
  /// Number of evictions because the buffer was full.
  [[nodiscard]] std::int64_t overflows() const { return overflows_; }

 private:
  Slot& At(int i) { return slots_[static_cast<std::size_t>((head_ + i) % capacity_)]; }
  const Slot& At(int i) const { return slots_[static_cast<std::size_t>((head_ + i) % capacity_)]; }
  // First position whose key is greater than the event's (binary search).
  int UpperBound(const Event& e) const {
    int lo = 0, hi = size_;
    while (lo < hi) {
      const int mid = (lo + hi) / 2;
      const Event& m = At(mid).event;
      const bool after = m.stamp > e.stamp || (m.stamp == e.stamp && m.order > e.order);
      if (after) {
        hi = mid;
      } else {
        lo = mid + 1;
      }
    }
    return lo;
  }
  void PopFront() {
    head_ = (head_ + 1) % capacity_;
    --size_;
  }
  // Keeps the newest event; drops those older than the lag window. The snapshot of the
  // first kept slot is at the stamp of the last dropped one, which is older than any event
  // still accepted, so every accepted event finds a snapshot at or before its stamp.
  void Prune() {
    while (size_ > 1 && At(0).event.stamp < newest_ - max_lag_) PopFront();
  }

  std::vector<Slot> slots_;
  int capacity_ = 0;
  double max_lag_ = 0.0;
  int head_ = 0;
  int size_ = 0;
  double newest_ = kNaN;
  std::int64_t replays_ = 0;
  std::int64_t overflows_ = 0;
};

}  // namespace fnmpc::estimation

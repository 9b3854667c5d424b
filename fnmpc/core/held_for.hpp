// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>
#include <limits>

namespace fnmpc {

/// Since when a condition has held without a break: the "held for T seconds" confirmations
/// of the controllers (touchdown, at take-off height, a neighbour on the ground or leaving the
/// formation, an unusable estimate). Times in seconds; no allocation.
class HeldFor {
 public:
  /// Records the condition at t: a run starts at its first true sample and ends at a false.
  void Update(bool condition, double t) {
    if (!condition) {
      Reset();
    } else {
      Start(t);
    }
  }
  /// Starts a run at t unless one is running.
  void Start(double t) {
    if (!running()) since_ = t;
  }
  /// Ends the run.
  void Reset() { since_ = std::numeric_limits<double>::quiet_NaN(); }
  [[nodiscard]] bool running() const { return std::isfinite(since_); }
  /// Start of the current run [s] (NaN: none).
  [[nodiscard]] double since() const { return since_; }
  /// A run has lasted at least `duration` at t (false without a run).
  [[nodiscard]] bool For(double t, double duration) const {
    return running() && t - since_ >= duration;
  }

 private:
  double since_ = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace fnmpc

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/formation_ties.hpp"

#include <cmath>

namespace fnmpc::formation {

NeighbourDeparture::NeighbourDeparture(double height, double time, double reacquire)
    : height_(height), time_(time), reacquire_(reacquire) {
  below_since_.fill(kNaN);
  back_since_.fill(kNaN);
  departed_.fill(false);
}

void NeighbourDeparture::Update(double t, const TieView* views, int n) {
  if (!(height_ > 0.0)) return;
  auto usable = [&](int k) {
    return views[k].available && !departed_[static_cast<std::size_t>(k)] &&
           std::isfinite(views[k].rel_z);
  };
  int leader = -1;
  for (int k = 0; k < n; ++k) {
    if (views[k].leader && usable(k)) leader = k;
  }
  for (int j = 0; j < n; ++j) {
    const auto sj = static_cast<std::size_t>(j);
    // The anchors' vertical formation errors of j: all below -height, all within height / 2.
    int anchors = 0;
    bool below = true, back = true;
    auto compare = [&](int k) {
      const double delta =
          (views[j].rel_z - views[k].rel_z) - (views[j].desired_z - views[k].desired_z);
      ++anchors;
      below = below && delta < -height_;
      back = back && std::abs(delta) < 0.5 * height_;
    };
    if (leader >= 0 && leader != j) {
      compare(leader);
    } else {
      for (int k = 0; k < n; ++k) {
        if (k != j && usable(k)) compare(k);
      }
      if (anchors < 2) anchors = 0;  // one follower as reference: cannot tell which left
    }
    const bool known = anchors > 0 && views[j].available && std::isfinite(views[j].rel_z);
    if (!departed_[sj]) {
      back_since_[sj] = kNaN;
      if (!(known && below)) {
        below_since_[sj] = kNaN;
        continue;
      }
      if (!std::isfinite(below_since_[sj])) below_since_[sj] = t;
      if (t - below_since_[sj] >= time_ - 1e-9) {
        departed_[sj] = true;
        below_since_[sj] = kNaN;
      }
    } else {
      // No anchor or no estimate: nothing tells it is back; it stays out.
      if (!(known && back)) {
        back_since_[sj] = kNaN;
        continue;
      }
      if (!std::isfinite(back_since_[sj])) back_since_[sj] = t;
      if (t - back_since_[sj] >= reacquire_ - 1e-9) {
        departed_[sj] = false;
        back_since_[sj] = kNaN;
      }
    }
  }
}

RecoveryReason TieLoss(const TieState* ties, int n, bool leader_seen_down) {
  if (leader_seen_down) return RecoveryReason::kLeaderDown;
  bool all_gone = n > 0;
  for (int j = 0; j < n; ++j) {
    const TieState& s = ties[j];
    const bool gone = !s.active && (s.landed || s.departed);
    if (s.leader && gone) return RecoveryReason::kLeaderDown;
    all_gone = all_gone && gone;
  }
  return all_gone ? RecoveryReason::kNeighboursGone : RecoveryReason::kNone;
}

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/formation_ties.hpp"

#include <cmath>

namespace fnmpc::formation {

NeighbourDeparture::NeighbourDeparture(double height, double time, double reacquire)
    : height_(height), time_(time), reacquire_(reacquire) {
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
    // In the cost: out after `time` below. Departed: back after `reacquire` within (no
    // anchor or no estimate: nothing tells it is back; it stays out). The other timer never
    // runs: each is reset when its own transition happens.
    const bool out = departed_[sj];
    HeldFor& held = out ? back_[sj] : below_[sj];
    held.Update(known && (out ? back : below), t);
    if (held.For(t, (out ? reacquire_ : time_) - 1e-9)) {
      departed_[sj] = !out;
      held.Reset();
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

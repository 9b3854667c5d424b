// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>

#include "fnmpc/core/held_for.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/formation/neighbour_limits.hpp"
#include "fnmpc/formation/recovery.hpp"

/// What a follower can tell about its formation ties from its own relative sensing, without
/// communication (docs/safety.md "A neighbour leaving the formation" and "A follower without
/// a tie to the leader"). Pure decisions from per-step facts, tested on their own.
namespace fnmpc::formation {

/// One formation neighbour as the follower sees it at one step.
struct TieView {
  double rel_z = kNaN;     ///< estimated p_j,z - p_self,z [m] (NaN: no estimate)
  double desired_z = 0.0;  ///< desired p_j,z - p_self,z [m] (either target frame: yaw only)
  bool leader = false;     ///< the neighbour is the formation's leader
  /// Could be in the cost apart from a departure: an accepted relative measurement within
  /// neighbour_timeout, a finite estimate, not dropped as landed.
  bool available = false;
};

/// Departure of formation neighbours that are evidently no longer flying the formation: a
/// neighbour j whose height relative to each of its anchors k, against the formation's,
///   delta_jk = (z_j - z_k) - (d_j,z - d_k,z),
/// is below -`height` for `time` departs; it returns after |delta_jk| < height / 2 for
/// `reacquire` (hysteresis). The follower's own motion cancels in delta_jk (it is the
/// vertical formation error between j and k, measured by the follower). Vertical only: in
/// healthy flight the neighbours' horizontal formation errors reach the size of a departure
/// (docs/safety.md), their vertical ones do not. Downwards only: a vehicle leaving the
/// formation (its autopilot landing it, a failsafe, motors off) leaves it downwards, and an
/// anchor that falls must not make the neighbour that stays up look departed. The
/// anchors of j: the leader when it is an available, not departed neighbour other than j
/// (the leader defines the formation); otherwise every other available, not departed
/// neighbour, at least two, all agreeing (with a single follower neighbour as reference the
/// two cannot be told apart). Fixed arrays: no allocation.
class NeighbourDeparture {
 public:
  /// height [m] (0: off), time and reacquire [s].
  NeighbourDeparture(double height, double time, double reacquire);
  /// One step at t [s] over `n` <= kMaxNeighbours neighbours (configuration order).
  void Update(double t, const TieView* views, int n);
  [[nodiscard]] bool departed(int j) const { return departed_.at(static_cast<std::size_t>(j)); }

 private:
  double height_, time_, reacquire_;
  std::array<HeldFor, kMaxNeighbours> below_{}, back_{};  // j below, back (departed)
  std::array<bool, kMaxNeighbours> departed_{};
};

/// One formation neighbour's state in the follower's cost.
struct TieState {
  bool leader = false;    ///< the neighbour is the formation's leader
  bool active = false;    ///< in the cost
  bool landed = false;    ///< out of the cost because seen on the ground
  bool departed = false;  ///< out of the cost because it left the formation (NeighbourDeparture)
};

/// Whether a follower in the NMPC phase has lost every formation tie that could lead to the
/// leader, and why (kNone: it has not):
///  - kLeaderDown: the leader is a neighbour and out of the cost because it landed or left
///    the formation, or `leader_seen_down` (the leader seen on the ground in a tracking slot
///    for neighbour_timeout): the leader is down for every follower, so no tie of anyone
///    leads to it any more;
///  - kNeighboursGone: every neighbour is out of the cost because it landed or left the
///    formation (a neighbour lost from view may be back; that is the estimate's timeout).
RecoveryReason TieLoss(const TieState* ties, int n, bool leader_seen_down);

}  // namespace fnmpc::formation

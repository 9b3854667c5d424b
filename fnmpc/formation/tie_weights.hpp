// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"

/// How a follower shares its formation-tie weight among its neighbours (string stability down
/// the graph, docs/results.md "Scale"). Pure arithmetic on the neighbours' graph depths,
/// which the formation's builder computes from the ties (formation::TieDepths).
///
/// Why by depth: a follower tracks the weighted mean of its neighbours' positions plus
/// offsets, so its own tracking error adds to the reference of every follower tied to it,
/// level after level. A tie to a neighbour of its own depth (a row-mate, which lags the row
/// ahead as much as it does) puts that lag back into its reference: with a share a on the
/// row ahead and the row-mate as fast as itself, a follower whose tracking responds as T(s)
/// follows the row ahead as a T / (1 - (1 - a) T), at low frequency a lag a^-1 times its own
/// per row (twice with equal weights, a = 1/2). Weighting only the ties towards the leader
/// (the lowest depth) gives a = 1: each row adds its own lag once. The row-mate ties stay in
/// the controller (relative-position bounds, collision avoidance, wake) and carry the weight
/// when every tie towards the leader has left the cost.
namespace fnmpc::formation {

/// The rules (scenario key `controller.tie_weights`).
enum class TieWeighting : int {
  kEqual = 0,  ///< every active tie weighted alike (the reference work)
  kDepth = 1,  ///< the active ties of the lowest neighbour depth share the weight
};
inline constexpr const char* kTieWeightingNames[] = {"equal", "depth"};
inline constexpr Choice kTieWeightingChoice{kTieWeightingNames, 2, 2};
inline const char* ToString(TieWeighting w) { return kTieWeightingNames[static_cast<int>(w)]; }

/// The weights w[0..n) of a follower's `n` ties under `rule`, from each neighbour's graph
/// depth (fewest ties from the leader; < 0: unknown) and whether the tie is in the cost.
/// Inactive ties get 0; the active ones sum to their count (the follower's total tie weight is
/// that of equal weights whatever the rule: a rule moves weight between ties, it does not
/// stiffen or soften the follower). When an active neighbour's depth is unknown the rule
/// cannot rank it and the weights are equal. No allocation.
void TieWeights(TieWeighting rule, const int* depth, const bool* active, int n, double* w);

/// Why discount a disagreeing tie: each tie asks for a place of the follower (the neighbour's
/// position minus the desired offset), and in healthy flight these places agree to within the
/// neighbours' formation errors (centimetres). A neighbour that leaves the formation (a dead
/// controller's autopilot drifting down and sideways, docs/safety.md) asks for a place that
/// moves away from the one its ties towards the leader ask for, and an equally weighted
/// follower follows half of that until the neighbour is dropped. The ties of the lowest
/// neighbour depth (nearest the leader) are the anchor: every deeper active tie's weight is
/// multiplied by 1 / (1 + (e_j / scale)^2), e_j the distance [m] between its place
/// `place[j]` and the anchor ties' mean place; then the active weights are scaled back to sum
/// to their count, as TieWeights leaves them. scale <= 0, fewer than two active ties, no
/// deeper tie or an unknown depth: `w` unchanged. `disagreement` (optional) receives per tie
/// the per-axis |place_j - anchor| of a discounted tie, zero for the others. Returns whether
/// a deeper tie was weighted (false exactly where `w` is left unchanged by the rules above; a
/// deeper tie that agrees exactly keeps its weight and still returns true). No allocation.
bool DiscountDisagreeingTies(const int* depth, const bool* active, const Vec3* place, double scale,
                             int n, double* w, Vec3* disagreement = nullptr);

}  // namespace fnmpc::formation

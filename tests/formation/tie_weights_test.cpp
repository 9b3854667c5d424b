// SPDX-License-Identifier: BSD-3-Clause
// Tie weights by graph depth (controller.tie_weights): the rules on their own, and the depths
// they rank the ties by, computed from a generated wedge's ties.
#include "fnmpc/formation/tie_weights.hpp"

#include <gtest/gtest.h>

#include <array>
#include <vector>

#include "fnmpc/formation/formation_shape.hpp"

namespace fnmpc::formation {
namespace {

std::array<double, 4> Weights(TieWeighting rule, std::array<int, 4> depth,
                              std::array<bool, 4> active, int n = 4) {
  std::array<double, 4> w{};
  w.fill(-1.0);
  TieWeights(rule, depth.data(), active.data(), n, w.data());
  return w;
}

TEST(TieWeightsTest, EqualWeighsEveryActiveTieOne) {
  const auto w = Weights(TieWeighting::kEqual, {0, 1, 3, 1}, {true, true, false, true});
  EXPECT_EQ(w, (std::array<double, 4>{1.0, 1.0, 0.0, 1.0}));
}

TEST(TieWeightsTest, DepthSharesTheWeightAmongTheLowestDepthTies) {
  // Given a follower at depth 3 tied to two vehicles of the row ahead and one row-mate
  const auto w = Weights(TieWeighting::kDepth, {2, 3, 2, 5}, {true, true, true, false});
  // Then the two ties towards the leader carry the whole weight (3, the active count)
  EXPECT_DOUBLE_EQ(w[0], 1.5);
  EXPECT_DOUBLE_EQ(w[2], 1.5);
  EXPECT_EQ(w[1], 0.0);
  EXPECT_EQ(w[3], 0.0);
  // And with the row ahead out of the cost, the row-mate takes it all
  const auto lost = Weights(TieWeighting::kDepth, {2, 3, 2, 5}, {false, true, false, false});
  EXPECT_EQ(lost, (std::array<double, 4>{0.0, 1.0, 0.0, 0.0}));
}

TEST(TieWeightsTest, AnUnknownDepthFallsBackToEqualWeights) {
  const auto unknown = Weights(TieWeighting::kDepth, {0, -1, 2, 0}, {true, true, true, false});
  EXPECT_EQ(unknown, (std::array<double, 4>{1.0, 1.0, 1.0, 0.0}));
  // An inactive tie's unknown depth does not matter
  const auto w = Weights(TieWeighting::kDepth, {0, 1, -1, 0}, {true, true, false, false});
  EXPECT_EQ(w, (std::array<double, 4>{2.0, 0.0, 0.0, 0.0}));
  // And no active tie: all zero
  const auto none = Weights(TieWeighting::kDepth, {0, 1, 2, 3}, {false, false, false, false});
  EXPECT_EQ(none, (std::array<double, 4>{0.0, 0.0, 0.0, 0.0}));
}

// The depths come from the ties (TieDepths), not from a hand-written list: in the generated
// 10-vehicle wedge the edge followers' second tie is a row-mate, which the depth rule leaves
// out, and the middle ones keep both ties to the row ahead.
TEST(TieWeightsTest, GeneratedWedgeRanksRowMatesBelowTheRowAhead) {
  FormationSpec spec;
  spec.count = 10;
  const std::vector<FormationSlot> slots = GenerateFormation(spec);
  std::vector<std::vector<int>> neighbours(slots.size());
  for (std::size_t i = 0; i < slots.size(); ++i)
    for (const FormationTie& t : slots[i].ties) neighbours[i].push_back(t.neighbour);
  const std::vector<int> depth = TieDepths(neighbours, 0);
  auto weights = [&](std::size_t i) {
    std::array<int, 4> d{};
    std::array<bool, 4> active{};
    for (std::size_t k = 0; k < neighbours[i].size(); ++k) {
      d[k] = depth[static_cast<std::size_t>(neighbours[i][k])];
      active[k] = true;
    }
    return Weights(TieWeighting::kDepth, d, active, static_cast<int>(neighbours[i].size()));
  };
  // f1 (depth 1): the leader and its row-mate f2
  EXPECT_EQ(neighbours[1], (std::vector<int>{0, 2}));
  EXPECT_DOUBLE_EQ(weights(1)[0], 2.0);
  EXPECT_EQ(weights(1)[1], 0.0);
  // f4 (depth 2, middle): f1 and f2, both of the row ahead
  EXPECT_EQ(neighbours[4], (std::vector<int>{1, 2}));
  EXPECT_DOUBLE_EQ(weights(4)[0], 1.0);
  EXPECT_DOUBLE_EQ(weights(4)[1], 1.0);
  // f9 (depth 3, edge): f5 of the row ahead and its row-mate f8
  EXPECT_EQ(neighbours[9], (std::vector<int>{5, 8}));
  EXPECT_DOUBLE_EQ(weights(9)[0], 2.0);
  EXPECT_EQ(weights(9)[1], 0.0);
}

}  // namespace
}  // namespace fnmpc::formation

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

// A row-mate that leaves its place loses its share to the tie towards the leader; agreeing
// ties keep equal weights.
TEST(TieWeightsTest, DisagreeingDeeperTieLosesItsShare) {
  // Given the triangle's follower1: the leader (depth 0) and follower2 (depth 1), equal rule
  const std::array<int, 2> depth{0, 1};
  const std::array<bool, 2> active{true, true};
  const auto discounted = [&](double e) {
    std::array<double, 2> w{1.0, 1.0};
    // The leader's tie asks for (1, 2, 0), follower2's for a place e away
    const std::array<Vec3, 2> place{Vec3(1.0, 2.0, 0.0),
                                    Vec3(1.0, 2.0, 0.0) + e * Vec3(0.6, 0.0, -0.8)};
    DiscountDisagreeingTies(depth.data(), active.data(), place.data(), 0.25, 2, w.data());
    return w;
  };
  // When follower2 asks for a place 2 cm off the leader's (healthy flight)
  const auto healthy = discounted(0.02);
  // Then the weights stay within 1 % of equal, and still sum to the active count
  EXPECT_NEAR(healthy[1], 1.0, 0.01);
  EXPECT_DOUBLE_EQ(healthy[0] + healthy[1], 2.0);
  // When it is as far off as the scale: the deeper tie's share halves relative to the anchor
  const auto half = discounted(0.25);
  EXPECT_DOUBLE_EQ(half[1] / half[0], 0.5);
  // And 1 m off: the follower follows under 6 % of it (w1 / (w0 + w1))
  const auto far = discounted(1.0);
  EXPECT_LT(far[1] / (far[0] + far[1]), 0.06);
  EXPECT_DOUBLE_EQ(far[0] + far[1], 2.0);
}

TEST(TieWeightsTest, DisagreementLeavesAnchorsUnknownDepthsAndTheOffSwitchAlone) {
  // Each place 0.8 m from the others' mean when deeper; the two anchors agree
  const std::array<Vec3, 3> place{Vec3(0.0, 1.0, 0.0), Vec3(0.0, 1.0, 0.0), Vec3(0.0, 1.8, 0.0)};
  // The return value says whether a weight was discounted (the controller rewrites its
  // references only then): false exactly where the weights are left unchanged.
  const auto run = [&](std::array<int, 3> depth, std::array<bool, 3> active, double scale) {
    std::array<double, 3> w{1.0, 1.0, active[2] ? 1.0 : 0.0};
    const std::array<double, 3> before = w;
    const bool discounted =
        DiscountDisagreeingTies(depth.data(), active.data(), place.data(), scale, 3, w.data());
    EXPECT_EQ(discounted, w != before);
    return w;
  };
  // Ties of one depth only (a rear follower tied to two vehicles of the row ahead): no anchor
  // to rank them by, equal weights
  EXPECT_EQ(run({2, 2, 2}, {true, true, true}, 0.25), (std::array<double, 3>{1.0, 1.0, 1.0}));
  // An unknown depth: unchanged
  EXPECT_EQ(run({0, -1, 1}, {true, true, true}, 0.25), (std::array<double, 3>{1.0, 1.0, 1.0}));
  // scale 0 switches it off
  EXPECT_EQ(run({0, 1, 1}, {true, true, true}, 0.0), (std::array<double, 3>{1.0, 1.0, 1.0}));
  // One active tie: unchanged
  EXPECT_EQ(run({0, 1, 1}, {false, true, false}, 0.25), (std::array<double, 3>{1.0, 1.0, 0.0}));
  // Two anchors and one deeper tie: the anchors share what the deeper one loses
  const auto w = run({1, 1, 2}, {true, true, true}, 0.4);
  EXPECT_DOUBLE_EQ(w[0], w[1]);
  EXPECT_NEAR(w[2] / w[0], 1.0 / (1.0 + 4.0), 1e-12);
  EXPECT_DOUBLE_EQ(w[0] + w[1] + w[2], 3.0);
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

// SPDX-License-Identifier: BSD-3-Clause
// What a follower tells about its formation ties from its own sensing: neighbours leaving
// the formation (NeighbourDeparture) and the loss of every tie to the leader (TieLoss).
#include "fnmpc/formation/formation_ties.hpp"

#include <gtest/gtest.h>

#include <array>

namespace fnmpc::formation {
namespace {

constexpr double kTs = 0.05;

/// The triangle's follower1: the leader (desired 0 m up) and follower2 (desired 0 m up).
std::array<TieView, 2> Triangle(double leader_z, double follower_z) {
  std::array<TieView, 2> v;
  v[0] = {leader_z, 0.0, true, true};
  v[1] = {follower_z, 0.0, false, true};
  return v;
}

TEST(NeighbourDepartureTest, NeighbourDescendingAwayFromTheLeaderDepartsAndReturns) {
  NeighbourDeparture d(0.5, 0.3, 0.5);
  int k = 0;  // step: t = k Ts
  auto run = [&](int until, double leader_z, double follower_z, int* first_change) {
    const bool before = d.departed(1);
    for (; k < until; ++k) {
      d.Update(k * kTs, Triangle(leader_z, follower_z).data(), 2);
      if (d.departed(1) != before && *first_change < 0) *first_change = k;
    }
  };
  int change = -1;
  // Given both neighbours in place (the follower itself 0.3 m low: it cancels),
  run(20, 0.3, 0.3, &change);
  EXPECT_EQ(change, -1);
  EXPECT_FALSE(d.departed(0));
  // when follower2 sinks 0.6 m below its place relative to the leader (from step 20),
  run(40, 0.3, -0.3, &change);
  // then it departs after the departure time (6 steps later), never the leader,
  EXPECT_EQ(change, 26);
  EXPECT_FALSE(d.departed(0));
  // it stays out while between half the height and the height (hysteresis),
  change = -1;
  run(60, 0.3, 0.0, &change);
  EXPECT_EQ(change, -1);
  EXPECT_TRUE(d.departed(1));
  // and returns after the reacquisition time back within half of it (10 steps).
  run(80, 0.3, 0.15, &change);
  EXPECT_EQ(change, 70);
  EXPECT_FALSE(d.departed(1));
}

TEST(NeighbourDepartureTest, ShortDipsAndCommonMotionDoNotDepart) {
  NeighbourDeparture d(0.5, 0.3, 0.5);
  double t = 0.0;
  // A 0.25 s dip of follower2 (shorter than the departure time),
  for (int k = 0; k < 5; ++k, t += kTs) d.Update(t, Triangle(0.0, -0.8).data(), 2);
  for (int k = 0; k < 5; ++k, t += kTs) d.Update(t, Triangle(0.0, 0.0).data(), 2);
  EXPECT_FALSE(d.departed(1));
  // both neighbours 2 m above the follower (it fell behind a climb: its own error),
  // follower2 0.45 m below its place (within the departure height), or 2 m above it (only
  // downward departures),
  for (int k = 0; k < 40; ++k, t += kTs) d.Update(t, Triangle(2.0, 2.0).data(), 2);
  for (int k = 0; k < 40; ++k, t += kTs) d.Update(t, Triangle(0.0, -0.45).data(), 2);
  for (int k = 0; k < 40; ++k, t += kTs) d.Update(t, Triangle(0.0, 2.0).data(), 2);
  EXPECT_FALSE(d.departed(0));
  EXPECT_FALSE(d.departed(1));
  // and the leader falling below a single follower neighbour: the follower that stays up does
  // not depart, and the leader departs only against two agreeing others
  for (int k = 0; k < 40; ++k, t += kTs) d.Update(t, Triangle(-2.0, 0.0).data(), 2);
  EXPECT_FALSE(d.departed(0));
  EXPECT_FALSE(d.departed(1));
  // and with departure off nothing departs.
  NeighbourDeparture off(0.0, 0.3, 0.5);
  for (int k = 0; k < 40; ++k, t += kTs) off.Update(t, Triangle(0.0, -2.0).data(), 2);
  EXPECT_FALSE(off.departed(1));
}

TEST(NeighbourDepartureTest, WithoutTheLeaderTwoAgreeingNeighboursAnchor) {
  NeighbourDeparture d(0.5, 0.3, 0.5);
  // Three follower neighbours with different desired heights; neighbour 1 1 m below its place
  std::array<TieView, 3> v;
  v[0] = {0.5, 0.5, false, true};
  v[1] = {-1.0, 0.0, false, true};
  v[2] = {-0.2, -0.2, false, true};
  for (double t = 0.0; t < 1.0; t += kTs) d.Update(t, v.data(), 3);
  EXPECT_FALSE(d.departed(0));
  EXPECT_TRUE(d.departed(1));
  EXPECT_FALSE(d.departed(2));
  // With two follower neighbours only, no anchor: nothing departs
  NeighbourDeparture two(0.5, 0.3, 0.5);
  for (double t = 0.0; t < 1.0; t += kTs) two.Update(t, v.data(), 2);
  EXPECT_FALSE(two.departed(1));
  // and a neighbour that is not available (no fresh measurement) departs from nothing.
  NeighbourDeparture gone(0.5, 0.3, 0.5);
  v[1].available = false;
  for (double t = 0.0; t < 1.0; t += kTs) gone.Update(t, v.data(), 3);
  EXPECT_FALSE(gone.departed(1));
}

TEST(TieLossTest, LeaderDownOrEveryNeighbourGone) {
  // Leader in the cost, follower2 departed: still tied to the leader
  std::array<TieState, 2> s{TieState{true, true, false, false},
                            TieState{false, false, false, true}};
  EXPECT_EQ(TieLoss(s.data(), 2, false), RecoveryReason::kNone);
  // the leader lost from view only (may be back; follower2 may still see it): no decision
  s[0] = {true, false, false, false};
  s[1] = {false, true, false, false};
  EXPECT_EQ(TieLoss(s.data(), 2, false), RecoveryReason::kNone);
  // the leader dropped as landed: down for everyone, even with follower2 in the cost
  s[0].landed = true;
  EXPECT_EQ(TieLoss(s.data(), 2, false), RecoveryReason::kLeaderDown);
  // or seen on the ground in a tracking slot
  std::array<TieState, 1> f{TieState{false, true, false, false}};
  EXPECT_EQ(TieLoss(f.data(), 1, false), RecoveryReason::kNone);
  EXPECT_EQ(TieLoss(f.data(), 1, true), RecoveryReason::kLeaderDown);
  // every follower neighbour landed or departed
  std::array<TieState, 2> g{TieState{false, false, true, false},
                            TieState{false, false, false, true}};
  EXPECT_EQ(TieLoss(g.data(), 2, false), RecoveryReason::kNeighboursGone);
  // but one of them merely lost from view: no decision
  g[1].departed = false;
  EXPECT_EQ(TieLoss(g.data(), 2, false), RecoveryReason::kNone);
}

}  // namespace
}  // namespace fnmpc::formation

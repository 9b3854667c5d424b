// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/trajectory.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace fnmpc::formation {
namespace {

TEST(TrajectoryTest, QuinticLegsStartAndEndAtRestAndHold) {
  // Given two legs of 2 s with 1 s holds
  const auto tr =
      WaypointTrajectory::Uniform({Vec3::Zero(), Vec3(1, 0, 0), Vec3(1, 2, 0)}, 2.0, 1.0);
  Vec3 p, v, a;
  // Then the reference rests at the start before t = 0, is half way with peak speed in the middle
  tr.Sample(-1.0, &p, &v);
  EXPECT_TRUE(p.isZero());
  tr.Sample(1.0, &p, &v, &a);
  EXPECT_NEAR(p.x(), 0.5, 1e-12);
  EXPECT_NEAR(v.x(), 1.875 / 2.0, 1e-12);
  EXPECT_NEAR(a.x(), 0.0, 1e-12);
  // and holds the waypoint, then finishes at the last one
  tr.Sample(2.5, &p, &v);
  EXPECT_TRUE(p.isApprox(Vec3(1, 0, 0)));
  EXPECT_TRUE(v.isZero());
  EXPECT_EQ(tr.TimeSinceStop(1.0), 0.0);
  EXPECT_NEAR(tr.TimeSinceStop(2.5), 0.5, 1e-12);
  tr.Sample(100.0, &p, &v);
  EXPECT_TRUE(p.isApprox(Vec3(1, 2, 0)));
  EXPECT_DOUBLE_EQ(tr.end_of_motion(), 5.0);
  EXPECT_DOUBLE_EQ(tr.duration(), 6.0);
}

TEST(TrajectoryTest, ReferenceIsContinuous) {
  // Given a three-leg trajectory
  const auto tr = WaypointTrajectory::Uniform(
      {Vec3::Zero(), Vec3(1, 1, 0), Vec3(0, 1, 1), Vec3::Zero()}, 1.5, 0.5);
  Vec3 p0, v0, p1, v1;
  // Then positions and velocities have no jumps at any 1 ms step
  for (double t = -0.1; t < 6.5; t += 1e-3) {
    tr.Sample(t, &p0, &v0);
    tr.Sample(t + 1e-3, &p1, &v1);
    EXPECT_LT((p1 - p0).norm(), 3e-3) << t;
    EXPECT_LT((v1 - v0).norm(), 1e-2) << t;
  }
}

TEST(TrajectoryTest, RandomWalkStaysInTheBoxAndIsReproducible) {
  // Given a manual-leader walk in a 1.5 m^3 box
  const Vec3 box = Vec3::Constant(1.145);
  const auto a = WaypointTrajectory::RandomWalk(box, 10, 1.0, 2.0, 2.0, 3.0, 42);
  const auto b = WaypointTrajectory::RandomWalk(box, 10, 1.0, 2.0, 2.0, 3.0, 42);
  const auto c = WaypointTrajectory::RandomWalk(box, 10, 1.0, 2.0, 2.0, 3.0, 43);
  // Then every sample is inside the box, the same seed gives the same walk, another seed not
  Vec3 p, v, q, w;
  for (double t = 0.0; t < a.duration(); t += 0.01) {
    a.Sample(t, &p, &v);
    b.Sample(t, &q, &w);
    EXPECT_TRUE((p.cwiseAbs().array() <= box.array() / 2 + 1e-12).all()) << t;
    EXPECT_EQ(p, q);
  }
  EXPECT_NE(a.points()[3], c.points()[3]);
}

TEST(TrajectoryTest, RejectsBadDurations) {
  EXPECT_THROW(WaypointTrajectory({Vec3::Zero(), Vec3::Ones()}, {0.0}, {1.0}),
               std::invalid_argument);
  EXPECT_THROW(WaypointTrajectory({Vec3::Zero(), Vec3::Ones()}, {1.0}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::formation

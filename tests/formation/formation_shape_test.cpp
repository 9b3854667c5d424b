// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/formation_shape.hpp"

#include <gtest/gtest.h>

#include <set>
#include <stdexcept>
#include <utility>

#include "fnmpc/formation/neighbour_limits.hpp"

namespace fnmpc::formation {
namespace {

FormationSpec Spec(FormationShape shape, int count, int ties = 2) {
  FormationSpec s;
  s.shape = shape;
  s.count = count;
  s.ties = ties;
  return s;
}

// The 10-vehicle wedge written by hand in config/scenarios/stress/wedge10-fast.yaml
// (rows 2.5 m apart, two ties per follower): the generator reproduces its starts and ties.
TEST(FormationShape, WedgeOfTenIsTheHandWrittenOne) {
  const std::vector<FormationSlot> w = GenerateFormation(Spec(FormationShape::kWedge, 10));
  ASSERT_EQ(w.size(), 10u);
  const std::vector<std::pair<double, double>> start = {
      {0, 0},   {-2.5, 2.5}, {-2.5, -2.5}, {-5, 5},      {-5, 0},
      {-5, -5}, {-7.5, 7.5}, {-7.5, 2.5},  {-7.5, -2.5}, {-7.5, -7.5}};
  const std::vector<std::vector<int>> ties = {{},     {0, 2}, {0, 1}, {1, 4}, {1, 2},
                                              {2, 4}, {3, 7}, {3, 4}, {4, 5}, {5, 8}};
  const std::vector<int> depth = {0, 1, 1, 2, 2, 2, 3, 3, 3, 3};
  for (std::size_t i = 0; i < w.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_DOUBLE_EQ(w[i].start.x(), start[i].first);
    EXPECT_DOUBLE_EQ(w[i].start.y(), start[i].second);
    EXPECT_EQ(w[i].start.z(), 0.0);
    EXPECT_EQ(w[i].depth, depth[i]);
    ASSERT_EQ(w[i].ties.size(), ties[i].size());
    for (std::size_t k = 0; k < ties[i].size(); ++k) {
      EXPECT_EQ(w[i].ties[k].neighbour, ties[i][k]);
      const Vec3 d = w[static_cast<std::size_t>(ties[i][k])].start - w[i].start;
      EXPECT_TRUE(w[i].ties[k].desired.isApprox(d, 1e-12));
    }
  }
}

TEST(FormationShape, LineTiesToThePredecessors) {
  const std::vector<FormationSlot> l = GenerateFormation(Spec(FormationShape::kLine, 6, 2));
  for (std::size_t i = 1; i < l.size(); ++i) {
    EXPECT_EQ(l[i].depth, static_cast<int>(i + 1) / 2);  // ties to i - 1 and i - 2
    EXPECT_EQ(l[i].ties.front().neighbour, static_cast<int>(i) - 1);
    EXPECT_EQ(l[i].ties.size(), i == 1 ? 1u : 2u);
    EXPECT_DOUBLE_EQ(l[i].start.x(), -2.5 * static_cast<double>(i));
  }
}

TEST(FormationShape, GridAndCircleAreConnectedToTheLeader) {
  FormationSpec g = Spec(FormationShape::kGrid, 12);
  g.columns = 4;
  const std::vector<FormationSlot> grid = GenerateFormation(g);
  EXPECT_DOUBLE_EQ(grid[11].start.x(), -2 * 2.5);  // third row
  EXPECT_DOUBLE_EQ(grid[11].start.y(), -3 * 2.5);  // fourth column
  EXPECT_EQ(grid[11].depth, 5);                    // rows plus columns from the corner
  const std::vector<FormationSlot> circle = GenerateFormation(Spec(FormationShape::kCircle, 9));
  for (std::size_t i = 1; i < circle.size(); ++i) {
    EXPECT_EQ(circle[i].ties.front().neighbour, 0);  // the leader in the centre first
    EXPECT_EQ(circle[i].depth, 1);
    EXPECT_GE(circle[i].start.norm(), 2.5 - 1e-12);
  }
}

// Every shape and size: ties within limits, distinct, not to itself, every follower
// reachable from the leader, starts at least `spacing` apart.
TEST(FormationShape, EveryShapeAndCountIsAValidFormation) {
  for (FormationShape shape : {FormationShape::kWedge, FormationShape::kLine, FormationShape::kGrid,
                               FormationShape::kCircle}) {
    for (int count : {2, 3, 7, 10, 28, 50, 100, 128}) {
      for (int ties : {1, 2, 3, kMaxNeighbours}) {
        SCOPED_TRACE(::testing::Message()
                     << static_cast<int>(shape) << " " << count << " " << ties);
        const std::vector<FormationSlot> f = GenerateFormation(Spec(shape, count, ties));
        ASSERT_EQ(f.size(), static_cast<std::size_t>(count));
        EXPECT_TRUE(f[0].ties.empty());
        for (std::size_t i = 1; i < f.size(); ++i) {
          EXPECT_GE(f[i].ties.size(), 1u);
          EXPECT_LE(f[i].ties.size(), static_cast<std::size_t>(ties));
          std::set<int> seen;
          for (const FormationTie& t : f[i].ties) {
            EXPECT_NE(t.neighbour, static_cast<int>(i));
            EXPECT_TRUE(seen.insert(t.neighbour).second);
          }
          EXPECT_GE(f[i].depth, 1);
          EXPECT_LT(f[i].depth, count);
          for (std::size_t j = 0; j < i; ++j)
            EXPECT_GE((f[i].start - f[j].start).norm(), 2.5 - 1e-9);
        }
      }
    }
  }
}

TEST(FormationShape, BadSpecsAreRefused) {
  EXPECT_THROW(GenerateFormation(Spec(FormationShape::kWedge, 1)), std::invalid_argument);
  EXPECT_THROW(GenerateFormation(Spec(FormationShape::kWedge, 5, 0)), std::invalid_argument);
  EXPECT_THROW(GenerateFormation(Spec(FormationShape::kWedge, 5, kMaxNeighbours + 1)),
               std::invalid_argument);
  FormationSpec s = Spec(FormationShape::kLine, 4);
  s.spacing = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(GenerateFormation(s), std::invalid_argument);
  FormationShape shape;
  EXPECT_TRUE(ParseFormationShape("grid", &shape));
  EXPECT_EQ(shape, FormationShape::kGrid);
  EXPECT_FALSE(ParseFormationShape("square", &shape));
}

}  // namespace
}  // namespace fnmpc::formation

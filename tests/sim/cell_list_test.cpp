// SPDX-License-Identifier: BSD-3-Clause
// Relative sensing through the cell list: the grid's candidates are a superset of
// the points in range, and a world sensing through it delivers exactly the measurements of
// the all-pairs test.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "fnmpc/sim/cell_list.hpp"
#include "fnmpc/sim/world.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

TEST(CellListTest, NearIsAnAscendingSupersetOfThePointsInRange) {
  // Given 300 random points over 60 x 40 m (z spread too) binned into 5 m cells,
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> x(-30.0, 30.0), y(-20.0, 20.0), z(0.0, 5.0);
  std::vector<Vec3> p;
  for (int i = 0; i < 300; ++i) p.emplace_back(x(rng), y(rng), z(rng));
  CellList cells;
  cells.Build(p, 5.0);
  std::vector<int> near;
  long candidates = 0;
  for (int q = 0; q < 300; ++q) {
    // When the points near each one within 5 m are asked for,
    cells.Near(p[q], 5.0, &near);
    candidates += static_cast<long>(near.size());
    // then the list is ascending and holds every point within 5 m.
    for (std::size_t k = 1; k < near.size(); ++k) ASSERT_LT(near[k - 1], near[k]);
    for (int j = 0; j < 300; ++j) {
      if ((p[j] - p[q]).norm() <= 5.0) {
        ASSERT_TRUE(std::binary_search(near.begin(), near.end(), j)) << q << " " << j;
      }
    }
  }
  // And it is far from all pairs (3 x 3 cells of 25 m^2 out of 2400 m^2: about 9 %).
  EXPECT_LT(candidates, 300L * 300L / 5);
}

TEST(CellListTest, FarApartPointsEnlargeTheCells) {
  // Given two clusters 10 km apart and 1 m cells (10^8 cells would be needed),
  std::vector<Vec3> p{Vec3(0, 0, 0), Vec3(0.5, 0, 0), Vec3(1e4, 1e4, 0), Vec3(1e4, 1e4 + 0.5, 0)};
  CellList cells;
  cells.Build(p, 1.0);
  // then the cells grew (at most 4 per point) and the near ones are still found.
  EXPECT_GE(cells.cell(), 1e4 / 4.0);
  std::vector<int> near;
  cells.Near(p[3], 1.0, &near);
  EXPECT_TRUE(std::binary_search(near.begin(), near.end(), 2));
}

// A world of `n` vehicles spread over 40 x 40 m with the default sensors (relative range
// 8 m) plus relative dropouts (the sensing draws random numbers per target), flown level.
std::vector<Measurement> FlyCrowd(int n, int index_min_vehicles, long* relative) {
  WorldConfig c = test::QuietConfig(n);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  for (VehicleSpec& v : c.vehicles) {
    v.sensors = SensorsConfig{};
    v.sensors.relative.dropout_probability = 0.1;
    v.position = Vec3(u(rng), u(rng), 1.5 + 0.02 * u(rng));  // z in [1.1, 1.9] m
  }
  c.gravity = 0.0;  // they drift apart slowly with the commands below
  c.relative_index_min_vehicles = index_min_vehicles;
  c.seed = 5;
  World world(c);
  for (int v = 0; v < n; ++v) {
    world.SetCommand(v, AttitudeCommand{0.2, 0.02 * (v % 5), -0.01 * (v % 3), 0.1 * v});
  }
  std::vector<Measurement> log;
  *relative = 0;
  Measurement m;
  for (int k = 0; k < 300; ++k) {
    world.StepOnce();
    while (world.PopMeasurement(&m)) {
      if (m.kind == SensorKind::kRelative) ++*relative;
      log.push_back(m);
    }
  }
  return log;
}

TEST(CellListTest, WorldSensesTheSameThroughTheGridAsThroughAllPairs) {
  // Given the same crowd of 60 vehicles sensed through the grid and by all pairs,
  long rel_grid = 0, rel_pairs = 0;
  const std::vector<Measurement> grid = FlyCrowd(60, 0, &rel_grid);
  const std::vector<Measurement> pairs = FlyCrowd(60, 1000, &rel_pairs);
  // then both deliver the same measurements bit for bit (same order, same noise draws),
  ASSERT_EQ(grid.size(), pairs.size());
  ASSERT_EQ(rel_grid, rel_pairs);
  for (std::size_t i = 0; i < grid.size(); ++i) {
    const Measurement &a = grid[i], &b = pairs[i];
    ASSERT_EQ(a.kind, b.kind);
    ASSERT_EQ(a.vehicle, b.vehicle);
    ASSERT_EQ(a.stamp, b.stamp);
    ASSERT_EQ(a.relative.target, b.relative.target);
    if (a.kind == SensorKind::kRelative) {
      ASSERT_EQ(a.relative.range, b.relative.range);
      ASSERT_EQ(a.relative.bearing, b.relative.bearing);
      ASSERT_EQ(a.relative.elevation, b.relative.elevation);
      ASSERT_EQ(a.relative.relative_yaw, b.relative.relative_yaw);
    } else if (a.kind == SensorKind::kImu) {
      ASSERT_EQ(a.accel, b.accel);
    }
  }
  // and the crowd is sparse: far fewer relative measurements than all pairs at 50 Hz
  // (60 x 59 pairs x 15 samples in 0.3 s), but many.
  EXPECT_GT(rel_grid, 1000);
  EXPECT_LT(rel_grid, 60L * 59L * 15L / 2);
}

}  // namespace
}  // namespace fnmpc::sim

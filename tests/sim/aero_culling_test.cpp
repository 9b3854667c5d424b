// SPDX-License-Identifier: BSD-3-Clause
// Spatial culling of the wakes (WorldConfig::aero_culling, AeroPass::Prepare): a wake is
// dropped only where the jet model gives exactly zero, so culled and full evaluation agree.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/sim/aero_pass.hpp"
#include "fnmpc/sim/downwash.hpp"
#include "fnmpc/sim/wake.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

TEST(AeroCullingTest, NoPointBeyondTheReachFeelsTheJet) {
  // Given random sources (tilts up to 60 degrees) and random points no lower than a floor,
  const DownwashSettings dw;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int inside = 0;
  for (int trial = 0; trial < 200000; ++trial) {
    const Vec3 source(0.0, 0.0, 2.0 + 3.0 * u(rng));
    const Vec3 axis = RotationZyx(0.5 * M_PI / 3 * (1 + u(rng)) * (u(rng) > 0 ? 1 : -1) / 2,
                                  M_PI / 3 * u(rng), 0.0)
                          .col(2);
    const double floor_z = 0.0;
    const Vec3 point(8.0 * u(rng), 8.0 * u(rng), floor_z + 2.5 * (1.0 + u(rng)));
    WakeSources src;
    src.Add(source, axis);
    const double reach = WakeHorizontalReach(dw, src, floor_z);
    // when the jet acts at a point,
    if (DownwashVelocity(dw, source, axis, 20.0, point).norm() == 0.0) continue;
    ++inside;
    // then the point is within the reach (horizontally) of the source and below its top.
    ASSERT_LE(std::hypot(point.x() - source.x(), point.y() - source.y()), reach)
        << "trial " << trial;
    ASSERT_LE(point.z(), WakeTop(dw, src)) << "trial " << trial;
  }
  EXPECT_GT(inside, 1000);
}

/// Two layers 1 m apart of a 4 x 4 grid at 1.5 m spacing, each upper vehicle stacked above a
/// lower one; the given aero models.
WorldConfig StackedGrid(bool reality, bool culling) {
  WorldConfig c = test::QuietConfig(32);
  c.downwash.enabled = true;
  c.reality.wake = reality;
  c.reality.rotor_aerodynamics = reality;
  c.wind.enabled = true;
  c.wind.velocity = Vec3(0.5, 0.2, 0.0);
  c.aero_culling = culling;
  const model::VehicleParams& p = c.vehicles[0].params;
  const double throttle = p.throttle.Throttle(p.mass * kGravity / 4.0, 16.8);
  for (int i = 0; i < 32; ++i) {
    const int cell = i % 16;
    c.vehicles[i].position = Vec3(1.5 * (cell % 4), 1.5 * (cell / 4), i < 16 ? 2.0 : 3.0);
    c.vehicles[i].initial_throttle = throttle;
  }
  return c;
}

void ExpectCulledEqualsFull(bool reality) {
  World culled(StackedGrid(reality, true));
  World full(StackedGrid(reality, false));
  double largest = 0.0;
  for (int k = 0; k < 1500; ++k) {
    culled.StepOnce();
    full.StepOnce();
    if (k % 50 != 49) continue;
    for (int i = 0; i < culled.num_vehicles(); ++i) {
      const TrueState a = culled.GetTrueState(i);
      const TrueState b = full.GetTrueState(i);
      ASSERT_EQ(a.aero_force, b.aero_force) << "vehicle " << i << " step " << k;
      ASSERT_EQ(a.aero_torque, b.aero_torque) << "vehicle " << i << " step " << k;
      ASSERT_EQ(a.position, b.position) << "vehicle " << i << " step " << k;
      largest = std::max(largest, a.aero_force.norm());
    }
  }
  // (the wakes did act: the lower layer is pushed by about a newton)
  EXPECT_GT(largest, 0.5);
}

TEST(AeroCullingTest, StackedGridAt1p5mCulledEqualsFullWithSteadyJets) {
  ExpectCulledEqualsFull(false);
}

TEST(AeroCullingTest, StackedGridAt1p5mCulledEqualsFullWithAdvectedWakes) {
  ExpectCulledEqualsFull(true);
}

TEST(AeroCullingTest, ALevelGridEvaluatesNoWakeAndAStackKeepsItsUpperWake) {
  // Given the stacked grid's kinematics at rest (upper layer 1 m above the lower),
  const WorldConfig c = StackedGrid(false, true);
  std::vector<detail::Kinematics> kin(c.vehicles.size());
  for (std::size_t i = 0; i < kin.size(); ++i) kin[i].position = c.vehicles[i].position;
  detail::AeroPass pass(c, static_cast<int>(kin.size()));
  pass.Prepare(kin);
  for (int i = 0; i < 32; ++i) {
    const std::vector<int>& s = pass.sources(i);
    if (i >= 16) {
      // an upper vehicle evaluates no wake (nothing above it, its level neighbours' jets
      // spread below it, the lower layer's act below the lower layer),
      EXPECT_TRUE(s.empty()) << "vehicle " << i;
    } else {
      // a lower one the wake of the vehicle above it, of the 31 others only a few.
      EXPECT_NE(std::find(s.begin(), s.end(), i + 16), s.end()) << "vehicle " << i;
      EXPECT_LE(s.size(), 5U) << "vehicle " << i;
    }
  }
}

}  // namespace
}  // namespace fnmpc::sim

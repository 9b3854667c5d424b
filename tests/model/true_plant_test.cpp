// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/model/true_plant.hpp"

#include "fnmpc/core/types.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace fnmpc::model {
namespace {

VehicleParams Nominal() {
  VehicleParams p;
  // The shipped vehicle's throttle map (config/vehicles/storm-drone-4.yaml).
  p.throttle.c.row(0) << 1.295532269, -0.1703711916, 0.008857434141, -0.0001635235747;
  p.throttle.c.row(1) << 0.2929197223, -0.01461840844, 0.0002619815754, 0.0;
  p.throttle.c.row(2) << -0.01292856667, 0.0002213855606, 0.0, 0.0;
  p.throttle.c.row(3) << 0.0003812494858, 0.0, 0.0, 0.0;
  return p;
}

TEST(TruePlantTest, VoltageDependenceScalingIsTheSubstitution) {
  // Given the shipped map and a 10 % error in its voltage dependence about 15 V,
  const VehicleParams p = Nominal();
  const ThrottlePolynomial q = ScaleVoltageDependence(p.throttle, 0.1, 15.0);
  // Then the re-expanded map equals the nominal map at V' = 15 + 1.1 (V - 15) everywhere,
  for (double f : {0.5, 3.3, 6.0}) {
    for (double v : {13.5, 15.0, 16.8}) {
      EXPECT_NEAR(q.Throttle(f, v), p.throttle.Throttle(f, 15.0 + 1.1 * (v - 15.0)), 1e-12);
    }
  }
  // keeps i + j <= 3, and a zero error is the identity.
  for (int i = 0; i < 4; ++i)
    for (int j = 4 - i; j < 4; ++j) EXPECT_EQ(q.c(i, j), 0.0);
  EXPECT_TRUE(ScaleVoltageDependence(p.throttle, 0.0, 15.0).c.isApprox(p.throttle.c, 1e-14));
}

TEST(TruePlantTest, ZeroSpreadGivesTheNominalPlantWithDrawnBiasesOnly) {
  PlantSpread s;
  s.mass = s.inertia = s.thrust_constant = s.torque_constant = s.motor_time_constant = 0.0;
  s.thrust_scale = s.voltage_dependence = s.attitude_gains = 0.0;
  s.attitude_bias_min = s.attitude_bias_max = 0.01;
  const VehicleParams p = Nominal();
  const TruePlant t = DrawTruePlant(p, 0.02, s, 7, 1);
  EXPECT_EQ(t.params.mass, p.mass);
  EXPECT_EQ(t.params.inertia, p.inertia);
  EXPECT_EQ(t.motor_time_constant, 0.02);
  EXPECT_EQ(t.params.bias.thrust_scale, 1.0);
  EXPECT_TRUE(t.params.throttle.c.isApprox(p.throttle.c, 1e-14));
  EXPECT_TRUE(t.params.has_bias);
  EXPECT_DOUBLE_EQ(std::abs(t.params.bias.roll), 0.01);
  EXPECT_DOUBLE_EQ(std::abs(t.params.bias.pitch), 0.01);
}

TEST(TruePlantTest, DrawsAreDeterministicPerSeedAndVehicleAndFollowTheSpread) {
  const PlantSpread s;  // the documented defaults
  const VehicleParams p = Nominal();
  const TruePlant a = DrawTruePlant(p, 0.02, s, 3, 0);
  const TruePlant b = DrawTruePlant(p, 0.02, s, 3, 0);
  const TruePlant c = DrawTruePlant(p, 0.02, s, 3, 1);
  EXPECT_EQ(a.params.mass, b.params.mass);
  EXPECT_EQ(a.params.bias.roll, b.params.bias.roll);
  EXPECT_NE(a.params.mass, c.params.mass);
  // Over many seeds: the relative mass error has the spread's standard deviation and mean
  // 0, the thrust scale likewise, and every attitude bias lies in [min, max] in magnitude
  // with both signs about equally often.
  const int n = 4000;
  double sum = 0.0, sum2 = 0.0, ts = 0.0, ts2 = 0.0;
  int positive = 0;
  for (int k = 0; k < n; ++k) {
    const TruePlant t = DrawTruePlant(p, 0.02, s, 1000 + k, 0);
    const double e = t.params.mass / p.mass - 1.0;
    sum += e;
    sum2 += e * e;
    const double g = t.params.bias.thrust_scale - 1.0;
    ts += g;
    ts2 += g * g;
    for (double bias : {t.params.bias.roll, t.params.bias.pitch}) {
      ASSERT_GE(std::abs(bias), s.attitude_bias_min - 1e-15);
      ASSERT_LE(std::abs(bias), s.attitude_bias_max + 1e-15);
      positive += bias > 0.0 ? 1 : 0;
    }
  }
  EXPECT_NEAR(sum / n, 0.0, 4.0 * s.mass / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(sum2 / n), s.mass, 0.05 * s.mass);
  EXPECT_NEAR(ts / n, 0.0, 4.0 * s.thrust_scale / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(ts2 / n), s.thrust_scale, 0.05 * s.thrust_scale);
  EXPECT_NEAR(positive / (2.0 * n), 0.5, 0.03);
}

TEST(TruePlantTest, RejectsSpreadsThatCouldMakeAParameterNonPositive) {
  PlantSpread s;
  s.mass = 0.4;
  EXPECT_THROW(s.Validate(), std::invalid_argument);
  s = PlantSpread{};
  s.attitude_bias_min = 0.05;
  s.attitude_bias_max = 0.01;
  EXPECT_THROW(s.Validate(), std::invalid_argument);
}

TEST(TruePlantTest, EveryDrawIsARealisableBodyAndTheOtherDrawsStayTheSeeds) {
  // Given the largest spread the key accepts (0.33: independent per-axis factors in
  // [0.01, 1.99]), for which the first draw breaks the triangle inequality for some seeds
  // (Iyy > Ixx + Izz: MuJoCo refuses such a body),
  PlantSpread wide;
  wide.inertia = 0.33;
  PlantSpread none = wide;
  none.inertia = 0.0;
  const VehicleParams p = Nominal();
  // The first draw of the inertia factors, as DrawTruePlant makes it (its generator: the
  // mass factor, then one per axis).
  const auto first_draw = [&](std::uint64_t seed) {
    std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32), 0u,
                      0x91A47u};
    std::mt19937_64 rng(seq);
    std::normal_distribution<double> normal(0.0, 1.0);
    normal(rng);  // the mass
    Vec3 inertia;
    for (int a = 0; a < 3; ++a) {
      inertia[a] = p.inertia[a] * (1.0 + wide.inertia * std::clamp(normal(rng), -3.0, 3.0));
    }
    return inertia;
  };
  int redrawn = 0;
  for (int k = 0; k < 2000; ++k) {
    const std::uint64_t seed = 500 + static_cast<std::uint64_t>(k);
    const TruePlant t = DrawTruePlant(p, 0.02, wide, seed, 0);
    // then every drawn body is realisable,
    ASSERT_EQ(UnrealisableInertia(t.params.inertia), "") << "seed " << seed;
    // a realisable first draw is kept as it was (the shipped seeds' plants do not change),
    // an unrealisable one is drawn again,
    const Vec3 first = first_draw(seed);
    if (UnrealisableInertia(first).empty()) {
      ASSERT_EQ(t.params.inertia, first) << "seed " << seed;
    } else {
      ++redrawn;
    }
    // and every other parameter is the seed's, as without an inertia spread.
    const TruePlant u = DrawTruePlant(p, 0.02, none, seed, 0);
    ASSERT_EQ(t.params.mass, u.params.mass);
    ASSERT_EQ(t.params.bias.roll, u.params.bias.roll);
    ASSERT_EQ(t.params.attitude_kd[2], u.params.attitude_kd[2]);
    ASSERT_EQ(t.motor_time_constant, u.motor_time_constant);
  }
  EXPECT_GT(redrawn, 0);  // the case the redraw is for occurs at this spread
  std::printf("inertia spread 0.33: %d of 2000 first draws unrealisable, drawn again\n", redrawn);
  // A nominal body that is itself not realisable draws none: PlantDrawError naming the key.
  VehicleParams flat = p;
  flat.inertia = Vec3(0.01, 0.01, 0.03);
  PlantSpread narrow;
  narrow.inertia = 0.01;
  try {
    DrawTruePlant(flat, 0.02, narrow, 1, 0);
    ADD_FAILURE() << "an unrealisable nominal body was drawn";
  } catch (const PlantDrawError& e) {
    EXPECT_EQ(e.key(), "inertia");
    EXPECT_NE(std::string(e.what()).find("triangle inequality"), std::string::npos) << e.what();
  }
}

TEST(TruePlantTest, UnrealisableInertiaNamesTheBrokenInequality) {
  EXPECT_EQ(UnrealisableInertia(Vec3(0.0123, 0.0136, 0.0107)), "");  // the shipped vehicle
  EXPECT_EQ(UnrealisableInertia(Vec3(1.0, 1.0, 2.0)), "");           // a flat plate: equality
  EXPECT_NE(UnrealisableInertia(Vec3(1.0, 1.0, 2.001)).find("Izz"), std::string::npos);
  EXPECT_NE(UnrealisableInertia(Vec3(3.0, 1.0, 1.0)).find("Ixx"), std::string::npos);
  EXPECT_NE(UnrealisableInertia(Vec3(1.0, 0.0, 1.0)).find("positive definite"), std::string::npos);
  EXPECT_NE(UnrealisableInertia(Vec3(1.0, 1.0, std::nan(""))).find("Izz"), std::string::npos);
  VehicleParams v;
  v.inertia = Vec3(0.01, 0.01, 0.03);
  EXPECT_THROW(v.Validate(), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::model

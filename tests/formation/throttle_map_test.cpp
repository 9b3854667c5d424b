// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/throttle_map.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace fnmpc::formation {
namespace {

// Polynomial of config/vehicles/storm-drone-4.yaml.
model::ThrottlePolynomial StormDronePolynomial() {
  model::ThrottlePolynomial p;
  p.c(0, 0) = 1.295532269;
  p.c(0, 1) = -0.1703711916;
  p.c(0, 2) = 0.008857434141;
  p.c(0, 3) = -0.0001635235747;
  p.c(1, 0) = 0.2929197223;
  p.c(1, 1) = -0.01461840844;
  p.c(1, 2) = 0.0002619815754;
  p.c(2, 0) = -0.01292856667;
  p.c(2, 1) = 0.0002213855606;
  p.c(3, 0) = 0.0003812494858;
  return p;
}

TEST(ThrottleMapTest, LowerVoltageNeedsMoreThrottleForTheSameThrust) {
  // Given the hover thrust of the shipped vehicle
  const auto p = StormDronePolynomial();
  const double hover = 1.37 * 9.81;
  // When it is converted at a full and at a drained battery
  const double full = ThrustToThrottle(p, hover, 16.8);
  const double drained = ThrustToThrottle(p, hover, 14.0);
  // Then the drained battery needs a clearly larger throttle, both inside (0, 1)
  EXPECT_GT(full, 0.2);
  EXPECT_LT(drained, 1.0);
  EXPECT_GT(drained - full, 0.02);
}

TEST(ThrottleMapTest, RoundTripRecoversTheThrust) {
  // Given thrusts across the flight envelope and voltages across the discharge
  const auto p = StormDronePolynomial();
  for (double v : {14.0, 15.2, 16.8}) {
    for (double thrust : {6.0, 13.4, 20.0}) {
      // When converted to throttle and back
      const double throttle = ThrustToThrottle(p, thrust, v);
      // Then the thrust is recovered
      EXPECT_NEAR(ThrottleToThrust(p, throttle, v), thrust, 1e-6) << "V " << v << " T " << thrust;
    }
  }
}

TEST(ThrottleMapTest, InvalidInputsGiveNaNAndZeroThrustIdles) {
  const auto p = StormDronePolynomial();
  EXPECT_TRUE(std::isnan(ThrustToThrottle(p, 13.0, std::nan(""))));
  EXPECT_TRUE(std::isnan(ThrustToThrottle(p, std::nan(""), 16.0)));
  EXPECT_TRUE(std::isnan(ThrustToThrottle(p, 13.0, 0.0)));
  EXPECT_EQ(ThrustToThrottle(p, 0.0, 16.0), 0.0);
  EXPECT_EQ(ThrustToThrottle(p, 1e6, 16.0), 1.0);  // clamped
}

}  // namespace
}  // namespace fnmpc::formation

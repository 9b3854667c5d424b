// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "fnmpc/core/rotation.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

using test::QuietConfig;

TEST(WorldTest, HoversAtPolynomialThrottle) {
  // Given one vehicle 1 m up, rotors at the throttle the polynomial gives for m g / 4 at
  // a fixed 16.8 V.
  WorldConfig c = QuietConfig(1);
  c.battery.fixed_voltage = true;
  const model::VehicleParams& p = c.vehicles[0].params;
  const double throttle = p.throttle.Throttle(p.mass * kGravity / 4.0, 16.8);
  c.vehicles[0].initial_throttle = throttle;
  c.vehicles[0].position = Vec3(0.0, 0.0, 1.0);
  World world(c);
  // When it flies 5 s at that constant throttle,
  double max_dev = 0.0;
  for (int k = 0; k < 50; ++k) {
    world.Step(0.1);
    max_dev = std::max(max_dev, (world.GetTrueState(0).position - Vec3(0, 0, 1)).norm());
  }
  // Then it stays within 2 cm and the thrust equals the weight.
  EXPECT_LT(max_dev, 0.02);
  EXPECT_NEAR(world.GetTrueState(0).thrust, p.mass * kGravity, 1e-6);
  EXPECT_DOUBLE_EQ(world.GetTrueState(0).voltage, 16.8);
}

TEST(WorldTest, FreeFallFollowsGravity) {
  // Given a vehicle 50 m up with the rotors off and no ground,
  WorldConfig c = QuietConfig(1);
  c.ground = false;
  c.vehicles[0].position = Vec3(0.0, 0.0, 50.0);
  World world(c);
  const double dt = world.physics_dt();
  // When it falls for 2 s,
  for (int n = 1; n <= 2000; ++n) {
    world.StepOnce();
    const double t = n * dt;
    const double z = world.GetTrueState(0).position.z();
    // Then z follows the semi-implicit Euler recursion exactly, and the continuous
    // z0 - g t^2 / 2 within the integrator's O(dt) offset g t dt / 2.
    ASSERT_NEAR(z, 50.0 - kGravity * dt * dt * n * (n + 1) / 2.0, 1e-9);
    ASSERT_NEAR(z, 50.0 - kGravity * t * t / 2.0, kGravity * t * dt / 2.0 + 1e-9);
  }
  const TrueState s = world.GetTrueState(0);
  EXPECT_NEAR(s.velocity.z(), -kGravity * 2.0, 1e-9);
  EXPECT_NEAR(s.position.x(), 0.0, 1e-12);
  EXPECT_NEAR(s.euler.norm(), 0.0, 1e-12);
}

TEST(WorldTest, FreeBodyConservesAngularMomentum) {
  // Given a tumbling vehicle without gravity, ground or rotors,
  WorldConfig c = QuietConfig(1);
  c.ground = false;
  c.gravity = 0.0;
  c.vehicles[0].position = Vec3(0.0, 0.0, 5.0);
  World world(c);
  world.SetState(0, Vec3(0, 0, 5), Vec3(0.1, -0.2, 0.3), Vec3::Zero(), Vec3(2.0, -3.0, 5.0));
  const Vec3 inertia = c.vehicles[0].params.inertia;
  auto momentum = [&] {
    const TrueState s = world.GetTrueState(0);
    return Vec3(RotationZyx(s.euler.x(), s.euler.y(), s.euler.z()) *
                inertia.cwiseProduct(s.body_rates));
  };
  const Vec3 l0 = momentum();
  // When it spins freely for 2 s,
  double max_rel = 0.0;
  for (int k = 0; k < 20; ++k) {
    world.Step(0.1);
    max_rel = std::max(max_rel, (momentum() - l0).norm() / l0.norm());
  }
  // Then the world-frame angular momentum is conserved (the body rates are not).
  EXPECT_LT(max_rel, 5e-3);
  EXPECT_GT((world.GetTrueState(0).body_rates - Vec3(2.0, -3.0, 5.0)).norm(), 0.1);
}

TEST(WorldTest, LandedVehicleStaysLandedAtZeroThrottle) {
  // Given a vehicle on the ground with a zero thrust command,
  WorldConfig c = QuietConfig(1);
  c.vehicles[0].yaw = 0.7;
  World world(c);
  world.SetCommand(0, AttitudeCommand{0.0, 0.0, 0.0, 0.7});
  // When 5 s pass,
  world.Step(5.0);
  // Then it has not moved and rests on its feet.
  const TrueState s = world.GetTrueState(0);
  EXPECT_LT(s.position.head<2>().norm(), 1e-3);
  EXPECT_NEAR(s.position.z(), World::kRestHeight, 3e-3);
  EXPECT_LT(std::abs(s.euler.x()) + std::abs(s.euler.y()), 1e-3);
  EXPECT_NEAR(s.euler.z(), 0.7, 1e-3);
  EXPECT_LT(s.rotor_rpm.norm(), 1.0);
  EXPECT_LT(s.velocity.norm(), 1e-3);
}

TEST(WorldTest, ManyLandedVehiclesAllRestOnTheGround) {
  // Given 40 vehicles on the ground (MuJoCo's default contact buffer holds 25 on their feet)
  WorldConfig c = QuietConfig(40);
  World world(c);
  for (int i = 0; i < 40; ++i) world.SetCommand(i, AttitudeCommand{0.0, 0.0, 0.0, 0.0});
  // When 2 s pass at zero throttle
  world.Step(2.0);
  // Then every one of them still rests on its feet
  for (int i = 0; i < 40; ++i) {
    EXPECT_NEAR(world.GetTrueState(i).position.z(), World::kRestHeight, 3e-3) << "vehicle " << i;
  }
}

TEST(WorldTest, TakesOffAndLands) {
  // Given a landed vehicle under the autopilot,
  WorldConfig c = QuietConfig(1);
  World world(c);
  const double weight = c.vehicles[0].params.mass * kGravity;
  // When it climbs at 1.3 m g for 1 s, then descends at 0.9 m g,
  world.SetCommand(0, AttitudeCommand{1.3 * weight, 0.0, 0.0, 0.0});
  world.Step(1.0);
  const double z_top = world.GetTrueState(0).position.z();
  world.SetCommand(0, AttitudeCommand{0.95 * weight, 0.0, 0.0, 0.0});
  world.Step(6.0);
  world.SetCommand(0, AttitudeCommand{0.0, 0.0, 0.0, 0.0});
  world.Step(2.0);
  // Then it left the ground, came back and rests level on its feet.
  EXPECT_GT(z_top, 0.5);
  const TrueState s = world.GetTrueState(0);
  EXPECT_NEAR(s.position.z(), World::kRestHeight, 5e-3);
  EXPECT_LT(std::abs(s.euler.x()) + std::abs(s.euler.y()), 0.02);
  EXPECT_LT(s.velocity.norm(), 1e-2);
}

TEST(WorldTest, BatterySagReducesThrustAtFixedThrottle) {
  // Given a vehicle high up at a fixed throttle with a small battery,
  WorldConfig c = QuietConfig(1);
  c.ground = false;
  c.battery.capacity_ah = 0.3;
  c.vehicles[0].position = Vec3(0, 0, 500);
  c.vehicles[0].initial_throttle = 0.5;
  World world(c);
  EXPECT_DOUBLE_EQ(world.GetTrueState(0).voltage, 16.8);
  // When it flies,
  world.Step(1.0);
  const TrueState early = world.GetTrueState(0);
  world.Step(30.0);
  const TrueState late = world.GetTrueState(0);
  // Then the voltage sags under load and with discharge, and the thrust drops with it.
  EXPECT_LT(early.voltage, 16.8 - 0.1);  // load sag
  EXPECT_GT(early.current, 5.0);
  EXPECT_LT(late.soc, early.soc - 0.05);
  EXPECT_LT(late.voltage, early.voltage - 0.2);
  EXPECT_LT(late.thrust, early.thrust * 0.97);
  EXPECT_DOUBLE_EQ(late.throttle[0], 0.5);
}

TEST(WorldTest, BadConfigurationIsRejectedWithContext) {
  auto message = [](const WorldConfig& c) -> std::string {
    try {
      World w(c);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  WorldConfig c = QuietConfig(2);
  c.vehicles[1].params.mass = -1.0;
  EXPECT_NE(message(c).find("vehicle 1: [VehicleParams] mass"), std::string::npos) << message(c);
  c = QuietConfig(1);
  c.vehicles[0].params.inertia.y() = 0.0;
  EXPECT_NE(message(c).find("inertia"), std::string::npos);
  c = QuietConfig(1);
  c.vehicles[0].sensors.imu.enabled = true;
  c.vehicles[0].sensors.imu.rate_hz = 0.0;
  EXPECT_NE(message(c).find("vehicle 0 sensor 'imu': rate_hz must be > 0"), std::string::npos)
      << message(c);
  c = QuietConfig(1);
  c.vehicles[0].sensors.relative.enabled = true;
  c.vehicles[0].sensors.relative.rate_hz = -5.0;
  EXPECT_NE(message(c).find("'relative'"), std::string::npos);
  c = QuietConfig(1);
  c.physics_dt = 0.0;
  EXPECT_NE(message(c).find("physics_dt"), std::string::npos);
  c = QuietConfig(1);
  c.autopilot_rate_hz = -250.0;
  EXPECT_NE(message(c).find("autopilot_rate_hz"), std::string::npos);
  c = QuietConfig(1);
  c.vehicles[0].position.z() = 0.0;
  EXPECT_NE(message(c).find("kRestHeight"), std::string::npos);
  EXPECT_NE(message(WorldConfig{}).find("at least one vehicle"), std::string::npos);
  World w(QuietConfig(1));
  EXPECT_THROW(w.SetCommand(3, AttitudeCommand{}), std::invalid_argument);
  EXPECT_THROW(w.Step(-1.0), std::invalid_argument);
}

TEST(WorldTest, ModelCarriesMassAndInertia) {
  // Given the generated MJCF of two vehicles,
  const WorldConfig c = QuietConfig(2);
  const std::string xml = World::BuildMjcf(c);
  // Then each body has the vehicle's mass and inertia and four rotors.
  EXPECT_NE(xml.find("mass=\"1.37\" diaginertia=\"0.0123 0.0136 0.0107\""), std::string::npos);
  EXPECT_NE(xml.find("vehicle1_rotor3"), std::string::npos);
  EXPECT_NE(xml.find("type=\"plane\""), std::string::npos);
}

TEST(WorldTest, InstabilityStopsTheSimulationInsteadOfAResetIssue21) {
  // Given a vehicle whose velocity MuJoCo flags as diverged (above mjOption's 1e10 limit),
  WorldConfig c = QuietConfig(1);
  c.vehicles[0].position = Vec3(3.0, -2.0, 1.0);
  World world(c);
  world.SetState(0, Vec3(3.0, -2.0, 1.0), Vec3::Zero(), Vec3(1e12, 0.0, 0.0), Vec3::Zero());
  // When it steps, MuJoCo warns and would reset the world to the start (silently before):
  // the step throws, naming the time and the state before the step.
  try {
    world.StepOnce();
    FAIL() << "no SimulationError; vehicle at " << world.GetTrueState(0).position.transpose();
  } catch (const SimulationError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("MuJoCo instability at t = 0"), std::string::npos) << what;
    EXPECT_NE(what.find("vehicle 0 position (3, -2, 1)"), std::string::npos) << what;
    EXPECT_NE(what.find("velocity (1e+12"), std::string::npos) << what;
  }
}

TEST(WorldTest, FullContactBufferStopsTheSimulationInsteadOfDroppingContacts) {
  // Given three vehicles on their feet (12 contacts) and room for 1 contact per vehicle
  // (MuJoCo's buffer then holds 1 x (3 + 4) = 7),
  WorldConfig c = QuietConfig(3);
  c.contacts_per_vehicle = 1;
  World world(c);
  // When it steps, MuJoCo would drop the contacts beyond the buffer (feet through the
  // ground): the step throws, naming the room and the setting.
  try {
    world.StepOnce();
    FAIL() << "no SimulationError; vehicle 2 at z = " << world.GetTrueState(2).position.z();
  } catch (const SimulationError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("contact buffer is full at t = 0 s (room for 7 contacts"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("contacts_per_vehicle = 1 for 3 vehicles"), std::string::npos) << what;
  }
  // With room for two per vehicle (14) the same world steps on its feet.
  c.contacts_per_vehicle = 2;
  World roomy(c);
  roomy.Step(0.5);
  EXPECT_NEAR(roomy.GetTrueState(2).position.z(), World::kRestHeight, 3e-3);
  c.contacts_per_vehicle = 0;
  EXPECT_THROW(World{c}, std::invalid_argument);
}

TEST(WorldTest, SensorFasterThanPhysicsSamplesOncePerStep) {
  // A rate far above the physics rate must not step its sample index one at a time (1e9 Hz
  // hung the run); it samples once per physics step.
  WorldConfig c = QuietConfig(1);
  c.vehicles[0].sensors.imu.enabled = true;
  c.vehicles[0].sensors.imu.rate_hz = 1e9;
  World world(c);
  world.Step(0.01);
  int imu = 0;
  Measurement m;
  while (world.PopMeasurement(&m)) imu += m.kind == SensorKind::kImu ? 1 : 0;
  EXPECT_GE(imu, 9);
  EXPECT_LE(imu, 11);
}

}  // namespace
}  // namespace fnmpc::sim

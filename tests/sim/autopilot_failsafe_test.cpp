// SPDX-License-Identifier: BSD-3-Clause
// The emulated autopilot's command-timeout failsafe (level attitude, slow descent, land
// detector disarms) and the motors-off fault.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

using test::QuietConfig;

/// A world with one vehicle put at 2 m, level, at rest, with the failsafe switched as given.
struct Hovering {
  explicit Hovering(bool failsafe) : config(QuietConfig(1)) {
    config.command_timeout.enabled = failsafe;
    world = std::make_unique<World>(config);
    world->SetState(0, Vec3(0.0, 0.0, 2.0), Vec3(0.0, 0.0, 0.4), Vec3::Zero(), Vec3::Zero());
    weight = config.vehicles[0].params.mass * kGravity;
  }
  /// Sends a level hover command every 20 ms for `duration` [s].
  void Command(double duration) {
    for (double t = 0.0; t < duration - 1e-9; t += 0.02) {
      world->SetCommand(0, AttitudeCommand{weight, 0.0, 0.0, 0.4});
      world->Step(0.02);
    }
  }
  WorldConfig config;
  std::unique_ptr<World> world;
  double weight = 0.0;
};

TEST(AutopilotFailsafeTest, CommandTimeoutDescendsLevelAndDisarmsOnTheGround) {
  // Given a hovering vehicle whose command stream stops at t_last,
  Hovering h(true);
  const CommandTimeoutSettings& c = h.config.command_timeout;
  h.Command(0.5);
  const double t_last = h.world->GetAutopilotStatus(0).last_command_time;
  EXPECT_FALSE(h.world->GetAutopilotStatus(0).failsafe);
  EXPECT_TRUE(h.world->GetAutopilotStatus(0).armed);
  // When no command comes for longer than the timeout,
  h.world->Step(c.timeout - 0.05);
  EXPECT_FALSE(h.world->GetAutopilotStatus(0).failsafe) << "engaged before the timeout";
  h.world->Step(0.1);
  const AutopilotStatus engaged = h.world->GetAutopilotStatus(0);
  ASSERT_TRUE(engaged.failsafe);
  // Then it engages one autopilot period after the timeout at the latest,
  EXPECT_GE(engaged.failsafe_time, t_last + c.timeout);
  EXPECT_LE(engaged.failsafe_time, t_last + c.timeout + 1.0 / h.config.autopilot_rate_hz + 1e-9);
  // descends level at the descent speed with the yaw held,
  h.world->Step(1.5);
  TrueState s = h.world->GetTrueState(0);
  EXPECT_NEAR(s.velocity.z(), -c.descent_speed, 0.05);
  EXPECT_LT(std::abs(s.euler.x()) + std::abs(s.euler.y()), 0.02);
  EXPECT_NEAR(s.euler.z(), 0.4, 0.02);
  EXPECT_LT(s.velocity.head<2>().norm(), 0.05);
  // touches down at that speed (not a fall) and the land detector stops the motors.
  double touchdown_vz = kNaN;
  double touchdown_t = kNaN;
  for (int k = 0; k < 8000 && !h.world->GetAutopilotStatus(0).disarmed_by_failsafe; ++k) {
    h.world->StepOnce();
    s = h.world->GetTrueState(0);
    if (std::isnan(touchdown_vz) && s.position.z() < World::kRestHeight + 0.015) {
      touchdown_vz = s.velocity.z();
      touchdown_t = h.world->time();
    }
  }
  const AutopilotStatus down = h.world->GetAutopilotStatus(0);
  ASSERT_TRUE(down.disarmed_by_failsafe);
  ASSERT_TRUE(std::isfinite(touchdown_vz));
  EXPECT_GT(touchdown_vz, -1.0);
  EXPECT_GE(down.disarm_time, touchdown_t);
  EXPECT_LE(down.disarm_time, touchdown_t + c.land_detect_time + 0.5);
  h.world->Step(1.0);
  s = h.world->GetTrueState(0);
  EXPECT_LT(s.rotor_rpm.norm(), 1.0);
  EXPECT_NEAR(s.position.z(), World::kRestHeight, 5e-3);
  EXPECT_FALSE(h.world->GetAutopilotStatus(0).armed);
  // Latched: a late command does not restart the motors.
  h.world->SetCommand(0, AttitudeCommand{1.5 * h.weight, 0.0, 0.0, 0.0});
  h.world->Step(0.5);
  EXPECT_NEAR(h.world->GetTrueState(0).position.z(), World::kRestHeight, 5e-3);
}

TEST(AutopilotFailsafeTest, NoFailsafeWhenDisabledOrCommandsArriveInTime) {
  // Disabled (the default): the last command is held for ever.
  {
    Hovering h(false);
    h.Command(0.5);
    h.world->Step(3.0);
    EXPECT_FALSE(h.world->GetAutopilotStatus(0).failsafe);
    // still in the air at the commanded hover thrust (the failsafe would have landed it)
    EXPECT_GT(h.world->GetTrueState(0).position.z(), 0.5);
    EXPECT_NEAR(h.world->GetTrueState(0).thrust, h.weight, 0.05 * h.weight);
  }
  // Enabled, commands every 0.8 s (< 1 s timeout): never engages.
  {
    Hovering h(true);
    for (int k = 0; k < 5; ++k) {
      h.world->SetCommand(0, AttitudeCommand{h.weight, 0.0, 0.0, 0.4});
      h.world->Step(0.8);
    }
    EXPECT_FALSE(h.world->GetAutopilotStatus(0).failsafe);
  }
  // Enabled, a vehicle on the ground never armed (no command, or a zero thrust command).
  {
    WorldConfig c = QuietConfig(2);
    c.command_timeout.enabled = true;
    World w(c);
    w.SetCommand(1, AttitudeCommand{0.0, 0.0, 0.0, 0.0});
    w.Step(3.0);
    EXPECT_FALSE(w.GetAutopilotStatus(0).failsafe);
    EXPECT_FALSE(w.GetAutopilotStatus(1).failsafe);
    EXPECT_FALSE(w.GetAutopilotStatus(1).armed);
  }
}

TEST(AutopilotFailsafeTest, KilledMotorsFallFreely) {
  // Given a hovering vehicle,
  Hovering h(true);
  h.Command(0.5);
  const TrueState before = h.world->GetTrueState(0);
  // When its motors are killed,
  h.world->KillMotors(0);
  const double t0 = h.world->time();
  const AutopilotStatus st = h.world->GetAutopilotStatus(0);
  EXPECT_TRUE(st.motors_killed);
  EXPECT_DOUBLE_EQ(st.motors_killed_time, t0);
  // Then the thrust is zero at once, commands are ignored and it falls as a free body.
  h.world->SetCommand(0, AttitudeCommand{2.0 * h.weight, 0.0, 0.0, 0.0});
  const double fall = 0.3;
  h.world->Step(fall);
  const TrueState s = h.world->GetTrueState(0);
  EXPECT_DOUBLE_EQ(s.thrust, 0.0);
  const double expected_z =
      before.position.z() + before.velocity.z() * fall - 0.5 * kGravity * fall * fall;
  EXPECT_NEAR(s.position.z(), expected_z, 0.01);
  EXPECT_NEAR(s.velocity.z(), before.velocity.z() - kGravity * fall, 0.02);
  EXPECT_FALSE(h.world->GetAutopilotStatus(0).failsafe) << "a killed vehicle has no autopilot";
}

TEST(AutopilotFailsafeTest, BadSettingsAreRejected) {
  WorldConfig c = QuietConfig(1);
  c.command_timeout.timeout = 0.0;
  EXPECT_THROW(World{c}, std::invalid_argument);
  c = QuietConfig(1);
  c.command_timeout.descent_speed = -0.5;
  EXPECT_THROW(World{c}, std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::sim

// SPDX-License-Identifier: BSD-3-Clause
// The emulated flight controller's rules, driven by hand-made frames.
#include <gtest/gtest.h>

#include "tests/autopilot/link_pair.hpp"

namespace fnmpc::autopilot {
namespace {

using testing::FrameOf;
using testing::Hover;

struct Driver {
  explicit Driver(const EmulatedAutopilotSettings& s) : ap(s) {}
  EmulatedAutopilot ap;
  Outbox out;
  void Setpoint(double t) {
    ap.OnFrame(FrameOf(ToSetAttitudeTarget(Hover(), 0, 1, 1), 1, 191), t, &out);
  }
  int Command(double t, std::uint16_t cmd, float p1, float p2 = 0, float p3 = 0) {
    mavlink::CommandLong c;
    c.command = cmd;
    c.target_system = 1;
    c.param1 = p1;
    c.param2 = p2;
    c.param3 = p3;
    out.Clear();
    ap.OnFrame(FrameOf(c, 1, 191), t, &out);
    if (out.size() != 1) return -1;
    const auto* ack = std::get_if<mavlink::CommandAck>(&out[0]);
    if (ack == nullptr || ack->command != cmd || ack->target_system != 1) return -1;
    return ack->result;
  }
  int SetMode(double t, AutopilotKind k, FlightMode m) {
    const SetModeParams p = SetModeParamsOf(k, m);
    return Command(t, mav::kCmdDoSetMode, p.base_mode, p.custom_main, p.custom_sub);
  }
};

TEST(EmulatedAutopilotTest, Px4NeedsASetpointStreamOfMoreThanOneSecondBeforeOffboard) {
  Driver d{EmulatedAutopilotSettings{}};
  EXPECT_EQ(d.SetMode(0.0, AutopilotKind::kPx4, FlightMode::kOffboard),
            mav::kResultTemporarilyRejected);
  for (double t = 0.0; t < 0.95; t += 0.1) d.Setpoint(t);
  EXPECT_EQ(d.SetMode(0.95, AutopilotKind::kPx4, FlightMode::kOffboard),
            mav::kResultTemporarilyRejected);
  d.Setpoint(1.0);
  EXPECT_EQ(d.SetMode(1.0, AutopilotKind::kPx4, FlightMode::kOffboard),
            mav::kResultTemporarilyRejected);  // exactly 1 s is not more than 1 s
  d.Setpoint(1.05);
  EXPECT_EQ(d.SetMode(1.05, AutopilotKind::kPx4, FlightMode::kOffboard), mav::kResultAccepted);
  EXPECT_EQ(d.ap.mode(), FlightMode::kOffboard);
}

TEST(EmulatedAutopilotTest, Px4StreamSlowerThanTwoHertzDoesNotCount) {
  Driver d{EmulatedAutopilotSettings{}};
  for (double t = 0.0; t <= 3.0; t += 0.6) d.Setpoint(t);  // 1.7 Hz
  EXPECT_EQ(d.SetMode(3.0, AutopilotKind::kPx4, FlightMode::kOffboard),
            mav::kResultTemporarilyRejected);
}

TEST(EmulatedAutopilotTest, ArmingNeedsOffboardAndAStream) {
  Driver d{EmulatedAutopilotSettings{}};
  EXPECT_EQ(d.Command(0.0, mav::kCmdComponentArmDisarm, 1.0F), mav::kResultDenied);
  for (double t = 0.0; t <= 1.1 + 1e-9; t += 0.05) d.Setpoint(t);
  ASSERT_EQ(d.SetMode(1.1, AutopilotKind::kPx4, FlightMode::kOffboard), mav::kResultAccepted);
  EXPECT_EQ(d.Command(1.1, mav::kCmdComponentArmDisarm, 1.0F), mav::kResultAccepted);
  EXPECT_TRUE(d.ap.armed());
  EXPECT_TRUE(d.ap.Flying(1.1).valid());
}

TEST(EmulatedAutopilotTest, DisarmIsRefusedUntilTheLandDetectorConfirmsOrWhenForced) {
  for (const AutopilotKind kind : {AutopilotKind::kPx4, AutopilotKind::kArduPilot}) {
    EmulatedAutopilotSettings s;
    s.autopilot = kind;
    Driver d{s};
    for (double t = 0.0; t <= 1.1 + 1e-9; t += 0.05) d.Setpoint(t);
    ASSERT_EQ(d.SetMode(1.1, kind, FlightMode::kOffboard), mav::kResultAccepted);
    ASSERT_EQ(d.Command(1.1, mav::kCmdComponentArmDisarm, 1.0F), mav::kResultAccepted);
    // Flying the hover thrust: refused (PX4 "not landed", ArduPilot not land_complete)
    double t = 1.1;
    for (; t < 3.0; t += 0.05) {
      d.Setpoint(t);
      d.ap.Step(t, &d.out);
    }
    EXPECT_EQ(d.Command(t, mav::kCmdComponentArmDisarm, 0.0F),
              kind == AutopilotKind::kPx4 ? mav::kResultTemporarilyRejected : mav::kResultFailed);
    EXPECT_TRUE(d.ap.armed());
    // Idle on the ground for 1.1 s: accepted
    const AttitudeSetpoint idle{0.0, 0.0, 0.0, 0.0};
    for (const double end = t + 1.1; t < end; t += 0.05) {
      d.ap.OnFrame(FrameOf(ToSetAttitudeTarget(idle, 0, 1, 1), 1, 191), t, &d.out);
      d.ap.Step(t, &d.out);
    }
    EXPECT_EQ(d.Command(t, mav::kCmdComponentArmDisarm, 0.0F), mav::kResultAccepted);
    EXPECT_FALSE(d.ap.armed());
    EXPECT_FALSE(d.ap.Flying(t).valid());
  }
  // The documented emergency force (param2 21196) disarms in the air
  Driver f{EmulatedAutopilotSettings{}};
  for (double t = 0.0; t <= 1.1 + 1e-9; t += 0.05) f.Setpoint(t);
  ASSERT_EQ(f.SetMode(1.1, AutopilotKind::kPx4, FlightMode::kOffboard), mav::kResultAccepted);
  ASSERT_EQ(f.Command(1.1, mav::kCmdComponentArmDisarm, 1.0F), mav::kResultAccepted);
  EXPECT_EQ(f.Command(1.2, mav::kCmdComponentArmDisarm, 0.0F, 21196.0F), mav::kResultAccepted);
  EXPECT_FALSE(f.ap.armed());
}

TEST(EmulatedAutopilotTest, StreamsAtTheAutopilotsRatesUntilSetMessageIntervalChangesThem) {
  // Given PX4's onboard-mode defaults and the simulator's IMU at 250 Hz for 2 s
  Driver d{EmulatedAutopilotSettings{}};
  const auto count = [&](SensorKind kind, double rate, double from) {
    int n = 0;
    for (int i = 0; i < static_cast<int>(2.0 * rate); ++i) {
      n += d.ap.Streams(kind, from + i / rate) ? 1 : 0;
    }
    return n;
  };
  // Then HIGHRES_IMU goes at 50 Hz, SYS_STATUS at 5 Hz, motion capture untouched
  EXPECT_EQ(count(SensorKind::kImu, 250.0, 0.0), 100);
  EXPECT_EQ(count(SensorKind::kBattery, 10.0, 0.0), 10);
  EXPECT_EQ(count(SensorKind::kMocapPose, 60.0, 0.0), 120);
  // When the onboard computer asks for HIGHRES_IMU every 4000 us (250 Hz), it is accepted
  EXPECT_EQ(d.Command(2.0, mav::kCmdSetMessageInterval, 105.0F, 4000.0F), mav::kResultAccepted);
  EXPECT_EQ(count(SensorKind::kImu, 250.0, 2.0), 500);
  // A message it does not stream is refused; -1 stops a stream; 0 restores the default
  EXPECT_EQ(d.Command(4.0, mav::kCmdSetMessageInterval, 24.0F, 1000.0F), mav::kResultDenied);
  EXPECT_EQ(d.Command(4.0, mav::kCmdSetMessageInterval, 105.0F, -1.0F), mav::kResultAccepted);
  EXPECT_EQ(count(SensorKind::kImu, 250.0, 4.0), 0);
  EXPECT_EQ(d.Command(6.0, mav::kCmdSetMessageInterval, 105.0F, 0.0F), mav::kResultAccepted);
  EXPECT_EQ(count(SensorKind::kImu, 250.0, 6.0), 100);
  // ArduPilot streams no HIGHRES_IMU until asked
  EmulatedAutopilotSettings ardu;
  ardu.autopilot = AutopilotKind::kArduPilot;
  Driver a{ardu};
  EXPECT_FALSE(a.ap.Streams(SensorKind::kImu, 0.0));
  EXPECT_EQ(a.ap.StreamRate(SensorKind::kImu), 0.0);
}

TEST(EmulatedAutopilotTest, SetpointLossLandsAndRefusesOffboardAfterwards) {
  Driver d{EmulatedAutopilotSettings{}};
  for (double t = 0.0; t <= 1.1 + 1e-9; t += 0.05) d.Setpoint(t);
  d.SetMode(1.1, AutopilotKind::kPx4, FlightMode::kOffboard);
  d.Command(1.1, mav::kCmdComponentArmDisarm, 1.0F);
  d.ap.Step(2.0, &d.out);
  EXPECT_FALSE(d.ap.failsafe());
  d.ap.Step(2.2, &d.out);
  EXPECT_TRUE(d.ap.failsafe());
  EXPECT_EQ(d.ap.mode(), FlightMode::kLand);
  d.Setpoint(2.3);
  EXPECT_FALSE(d.ap.Flying(2.3).valid());
  EXPECT_EQ(d.SetMode(2.3, AutopilotKind::kPx4, FlightMode::kOffboard), mav::kResultDenied);
}

TEST(EmulatedAutopilotTest, HeartbeatCarriesModeArmedAndAutopilot) {
  EmulatedAutopilotSettings s;
  s.autopilot = AutopilotKind::kArduPilot;
  Driver d{s};
  d.Setpoint(0.0);
  ASSERT_EQ(d.SetMode(0.0, AutopilotKind::kArduPilot, FlightMode::kOffboard), mav::kResultAccepted);
  ASSERT_EQ(d.Command(0.0, mav::kCmdComponentArmDisarm, 1.0F), mav::kResultAccepted);
  d.out.Clear();
  d.ap.Step(0.0, &d.out);
  ASSERT_EQ(d.out.size(), 1U);
  const auto& hb = std::get<mavlink::Heartbeat>(d.out[0]);
  EXPECT_EQ(hb.custom_mode, 20U);  // GUIDED_NOGPS
  EXPECT_EQ(hb.autopilot, mav::kAutopilotArduPilotMega);
  EXPECT_NE(hb.base_mode & mav::kModeFlagSafetyArmed, 0);
  // Next heartbeat only after the period
  d.out.Clear();
  d.ap.Step(0.5, &d.out);
  EXPECT_EQ(d.out.size(), 0U);
}

TEST(EmulatedAutopilotTest, UnknownCommandsAreUnsupported) {
  Driver d{EmulatedAutopilotSettings{}};
  EXPECT_EQ(d.Command(0.0, 22 /* MAV_CMD_NAV_TAKEOFF */, 0.0F), mav::kResultUnsupported);
}

TEST(ModesTest, Px4AndArduPilotModeEncodings) {
  // PX4: custom_mode = main << 16 | sub << 24 (px4_custom_mode.h)
  EXPECT_EQ(CustomMode(AutopilotKind::kPx4, FlightMode::kOffboard), 6U << 16);
  EXPECT_EQ(CustomMode(AutopilotKind::kPx4, FlightMode::kLand), 4U << 16 | 6U << 24);
  EXPECT_EQ(ModeOf(AutopilotKind::kPx4, 6U << 16), FlightMode::kOffboard);
  EXPECT_EQ(ModeOf(AutopilotKind::kPx4, 4U << 16 | 4U << 24), FlightMode::kOther);  // LOITER
  // ArduPilot Copter: GUIDED_NOGPS = 20, LAND = 9, GUIDED (4) is not ours
  EXPECT_EQ(ModeOf(AutopilotKind::kArduPilot, 20), FlightMode::kOffboard);
  EXPECT_EQ(ModeOf(AutopilotKind::kArduPilot, 9), FlightMode::kLand);
  EXPECT_EQ(ModeOf(AutopilotKind::kArduPilot, 4), FlightMode::kOther);
  const SetModeParams p = SetModeParamsOf(AutopilotKind::kPx4, FlightMode::kOffboard);
  EXPECT_EQ(p.base_mode, 1.0F);
  EXPECT_EQ(p.custom_main, 6.0F);
  EXPECT_EQ(p.custom_sub, 0.0F);
  EXPECT_EQ(ModeOf(AutopilotKind::kPx4, SetModeParams{1.0F, kNaN, 0.0F}), FlightMode::kOther);
}

}  // namespace
}  // namespace fnmpc::autopilot

// SPDX-License-Identifier: BSD-3-Clause
// The onboard computer without its I/O (OnboardVehicle) against the emulated autopilot
// in memory: the take-off gate stops a vehicle whose autopilot never flies our setpoints, and
// only then (not when the autopilot disarms later); a take-off too early for the handshake is
// refused; with a working autopilot the setpoints sent carry the controller's throttle.
#include "fnmpc/onboard/onboard_vehicle.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <variant>

#include "fnmpc/autopilot/emulated_autopilot.hpp"
#include "fnmpc/autopilot/measurement_messages.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/onboard/controller_setup.hpp"
#include "tests/autopilot/link_pair.hpp"

namespace fnmpc::onboard {
namespace {

using autopilot::testing::FrameOf;

/// The triangle's leader (vehicle 0, MAVLink system 1) on the ground, its sensors on the link,
/// and an emulated autopilot: one 50 Hz control step per Step().
struct Bench {
  explicit Bench(autopilot::EmulatedAutopilotSettings ap, bool arm = true)
      : scenario(config::LoadScenarioFile(FNMPC_SOURCE_DIR "/config/scenarios/triangle.yaml")),
        config(Config(scenario, 5.0)),
        onboard(config, SessionFor(ap, arm), OnboardClock::kLocal),
        emulator(ap) {}

  static autopilot::SessionSettings SessionFor(const autopilot::EmulatedAutopilotSettings& ap,
                                               bool arm) {
    autopilot::SessionSettings s;
    s.autopilot = ap.autopilot;
    s.arm = arm;
    return s;
  }
  static formation::ControllerConfig Config(const config::ScenarioConfig& sc, double takeoff) {
    formation::ControllerConfig c = ControllerConfigFor(sc, 0, LeaderTrajectory(sc, sc.seed));
    c.takeoff_time = takeoff;
    return c;
  }

  /// The leader's measurements at rest on the ground at `t`, as its autopilot sends them.
  void Sense(double t) {
    for (const SensorKind kind :
         {SensorKind::kMocapPose, SensorKind::kImu, SensorKind::kCompass, SensorKind::kBattery}) {
      Measurement m;
      m.kind = kind;
      m.vehicle = 0;
      m.stamp = t;
      m.arrival = t;
      m.position = Vec3(0.0, 0.0, 0.05);
      m.euler = Vec3::Zero();
      m.accel = Vec3(0.0, 0.0, kGravity);
      m.gyro = Vec3::Zero();
      m.yaw = 0.0;
      m.voltage = 16.0;
      mavlink::Message msg;
      ASSERT_TRUE(autopilot::ToMessage(m, &msg)) << ToString(kind);
      onboard.OnFrame(FrameOf(msg, 1, 1), t);
    }
  }

  void Step() {
    autopilot::Outbox down, up, acks;
    emulator.Step(t, &down);
    for (const mavlink::Message& m : down) onboard.OnFrame(FrameOf(m, 1, 1), t);
    Sense(t);
    last = onboard.Step(t, &up);
    for (const mavlink::Message& m : up) {
      if (const auto* sp = std::get_if<mavlink::SetAttitudeTarget>(&m)) {
        ++setpoints;
        if (t > config.takeoff_time + 1e-9) ++setpoints_after_takeoff;
        max_thrust = std::max(max_thrust, static_cast<double>(sp->thrust));
      }
      emulator.OnFrame(FrameOf(m, 1, 191), t, &acks);
    }
    for (const mavlink::Message& m : acks) onboard.OnFrame(FrameOf(m, 1, 1), t);
    t += 0.02;
  }
  void RunUntil(double until) {
    while (t < until) Step();
  }

  config::ScenarioConfig scenario;
  formation::ControllerConfig config;
  OnboardVehicle onboard;
  autopilot::EmulatedAutopilot emulator;
  OnboardStep last;
  double t = 0.0;
  long setpoints = 0, setpoints_after_takeoff = 0;
  double max_thrust = 0.0;
};

autopilot::EmulatedAutopilotSettings ArduPilot(int guid_options) {
  autopilot::EmulatedAutopilotSettings s;
  s.autopilot = autopilot::AutopilotKind::kArduPilot;
  s.guid_options = guid_options;
  return s;
}

TEST(OnboardVehicleTest, ATakeoffTooEarlyForTheHandshakeIsRefused) {
  const config::ScenarioConfig sc =
      config::LoadScenarioFile(FNMPC_SOURCE_DIR "/config/scenarios/triangle.yaml");
  // The handshake's allowance (handshake_time, 5 s): a take-off at 4.5 s cannot be met.
  EXPECT_THROW(
      OnboardVehicle(Bench::Config(sc, 4.5), autopilot::SessionSettings{}, OnboardClock::kLocal),
      std::invalid_argument);
  EXPECT_NO_THROW(
      OnboardVehicle(Bench::Config(sc, 5.0), autopilot::SessionSettings{}, OnboardClock::kLocal));
}

TEST(OnboardVehicleTest, AVehicleNobodyArmsStopsAtTakeoff) {
  // Given a session that waits for the pilot to arm (arm: false) and a pilot who never does,
  Bench b(autopilot::EmulatedAutopilotSettings{}, /*arm=*/false);
  // when the take-off time passes,
  b.RunUntil(4.9);
  EXPECT_EQ(b.onboard.stop(), OnboardStop::kNone) << ToString(b.onboard.session().reason());
  EXPECT_FALSE(b.emulator.armed());
  b.RunUntil(6.0);
  // then the vehicle stopped at take-off, handed back, never sent a setpoint after the
  // take-off time nor a thrust above zero (the warm-up stream was sent).
  EXPECT_EQ(b.onboard.stop(), OnboardStop::kNotReadyAtTakeoff);
  EXPECT_TRUE(b.onboard.session().finished());
  EXPECT_GT(b.setpoints, 0);
  EXPECT_EQ(b.setpoints_after_takeoff, 0);
  EXPECT_EQ(b.max_thrust, 0.0);
}

TEST(OnboardVehicleTest, AnAutopilotThatRefusesToArmEndsTheSessionBeforeTakeoff) {
  // Given an ArduPilot without GUID_OPTIONS bit 3 (it refuses to arm),
  Bench b(ArduPilot(0));
  b.RunUntil(3.0);
  // then the session failed on the refusal before the take-off time, and nothing climbed.
  EXPECT_EQ(b.onboard.stop(), OnboardStop::kSession);
  EXPECT_EQ(b.onboard.session().reason(), autopilot::SessionReason::kCommandRejected);
  EXPECT_EQ(b.setpoints_after_takeoff, 0);
  EXPECT_EQ(b.max_thrust, 0.0);
}

TEST(OnboardVehicleTest, AFlyingSessionTakesOffAndALaterDisarmIsNotAMissedTakeoff) {
  // Given PX4 rules and a working handshake,
  Bench b(autopilot::EmulatedAutopilotSettings{});
  b.RunUntil(4.95);
  ASSERT_TRUE(b.onboard.session().active());
  ASSERT_TRUE(b.emulator.armed());
  // when the take-off time passes, the controller climbs through the autopilot: no stop,
  // setpoints with thrust (the identified throttle at 16 V) reach it;
  b.RunUntil(6.0);
  EXPECT_EQ(b.onboard.stop(), OnboardStop::kNone) << ToString(b.onboard.session().reason());
  EXPECT_EQ(b.last.control.phase, formation::FlightPhase::kTakeoff);
  EXPECT_GT(b.setpoints_after_takeoff, 40);
  EXPECT_GT(b.max_thrust, 0.1);
  EXPECT_LE(b.max_thrust, 1.0);
  EXPECT_TRUE(b.emulator.Flying(b.t).valid());
  // and when the autopilot disarms on its own (its land detector), the session hands back
  // with that reason: not a missed take-off although the session is no longer active.
  b.emulator.Disarm(b.t);
  b.RunUntil(6.5);
  EXPECT_EQ(b.onboard.stop(), OnboardStop::kSession);
  EXPECT_EQ(b.onboard.session().reason(), autopilot::SessionReason::kDisarmedByAutopilot);
}

}  // namespace
}  // namespace fnmpc::onboard

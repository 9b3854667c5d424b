// SPDX-License-Identifier: BSD-3-Clause
// The onboard session against the emulated PX4 and ArduPilot: handshakes, ACK handling and
// retries, watchdogs, hand-back and disarm.
#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

#include "tests/autopilot/link_pair.hpp"

namespace fnmpc::autopilot {
namespace {

using testing::Hover;
using testing::LinkPair;

SessionSettings Px4() { return SessionSettings{}; }
SessionSettings ArduPilot() {
  SessionSettings s;
  s.autopilot = AutopilotKind::kArduPilot;
  return s;
}
EmulatedAutopilotSettings EmulatedPx4() { return EmulatedAutopilotSettings{}; }
EmulatedAutopilotSettings EmulatedArduPilot() {
  EmulatedAutopilotSettings e;
  e.autopilot = AutopilotKind::kArduPilot;
  e.setpoint_timeout = 3.0;
  return e;
}

std::vector<SessionEvent> Events(AutopilotSession* s) {
  std::vector<SessionEvent> v;
  SessionEvent e;
  while (s->PopEvent(&e)) v.push_back(e);
  return v;
}

TEST(SessionTest, Px4OffboardHandshakeStreamsFirstThenSetsModeThenArms) {
  // Given a session and an emulated PX4
  LinkPair link(Px4(), EmulatedPx4());
  // When the session runs with a valid setpoint
  bool became_active = link.RunUntil(5.0, Hover(), [&] { return link.session.active(); });
  // Then it is active, the autopilot armed in OFFBOARD, flying our setpoint
  ASSERT_TRUE(became_active) << ToString(link.session.state());
  EXPECT_TRUE(link.autopilot.armed());
  EXPECT_EQ(link.autopilot.mode(), FlightMode::kOffboard);
  const AttitudeSetpoint flown = link.autopilot.Flying(link.t);
  ASSERT_TRUE(flown.valid());
  EXPECT_NEAR(flown.roll, Hover().roll, 1e-6);
  EXPECT_NEAR(flown.pitch, Hover().pitch, 1e-6);
  EXPECT_NEAR(flown.yaw, Hover().yaw, 1e-6);
  EXPECT_NEAR(flown.thrust, Hover().thrust, 1e-6);
  // And the mode was asked for only after more than 1 s of setpoints at 20 Hz
  const std::vector<SessionEvent> ev = Events(&link.session);
  ASSERT_GE(ev.size(), 4U);
  EXPECT_EQ(ev[0].state, SessionState::kWarmingUp);
  EXPECT_EQ(ev[1].state, SessionState::kRequestingMode);
  EXPECT_GE(ev[1].time - ev[0].time, 1.0 - 1e-9);
  EXPECT_GE(link.setpoints_seen, 20);
  EXPECT_EQ(ev[2].state, SessionState::kArming);
  EXPECT_EQ(ev[2].command, mav::kCmdDoSetMode);
  EXPECT_EQ(ev[2].result, mav::kResultAccepted);
  EXPECT_EQ(ev[3].state, SessionState::kActive);
  EXPECT_EQ(ev[3].command, mav::kCmdComponentArmDisarm);
}

TEST(SessionTest, Px4RefusesOffboardBeforeTheStreamAndTheSessionRetries) {
  // Given a session that asks for OFFBOARD at once (no warm-up)
  SessionSettings s = Px4();
  s.warmup = 0.0;
  s.command_timeout = 0.3;
  LinkPair link(s, EmulatedPx4());
  // When it runs
  bool rejected = false;
  const bool active = link.RunUntil(5.0, Hover(), [&] {
    double t = 0.0;
    rejected = rejected || link.autopilot.TakeEvent(&t) == EmulatorEvent::kModeRejected;
    return link.session.active();
  });
  // Then PX4 first refused (temporarily), and a resend after 1 s of stream succeeded, with
  // the confirmation field counting the resends
  EXPECT_TRUE(rejected);
  EXPECT_TRUE(active);
  EXPECT_GE(link.t, 1.0);
  EXPECT_GE(link.commands_seen, 3);
}

TEST(SessionTest, ArduPilotGuidedNoGpsHandshake) {
  LinkPair link(ArduPilot(), EmulatedArduPilot());
  ASSERT_TRUE(link.RunUntil(5.0, Hover(), [&] { return link.session.active(); }));
  EXPECT_EQ(link.autopilot.mode(), FlightMode::kOffboard);  // GUIDED_NOGPS
  EXPECT_EQ(CustomMode(AutopilotKind::kArduPilot, link.autopilot.mode()), 20U);
  EXPECT_TRUE(link.autopilot.Flying(link.t).valid());
}

TEST(SessionTest, ArduPilotWithoutThrustOptionRefusesToArmAndTheSessionFails) {
  // Given ArduPilot with GUID_OPTIONS bit 3 clear (thrust would be a climb rate)
  EmulatedAutopilotSettings e = EmulatedArduPilot();
  e.guid_options = 0;
  LinkPair link(ArduPilot(), e);
  // When the session runs
  link.RunUntil(5.0, Hover(), [&] { return link.session.finished(); });
  // Then arming is denied, the session failed with that reason and streams nothing more
  EXPECT_EQ(link.session.state(), SessionState::kFailed);
  EXPECT_EQ(link.session.reason(), SessionReason::kCommandRejected);
  EXPECT_FALSE(link.autopilot.armed());
  const long sent = link.setpoints_seen;
  link.Step(Hover());
  EXPECT_EQ(link.setpoints_seen, sent);
}

TEST(SessionTest, StateStreamLossHandsBackWithinTheTimeoutAndTheAutopilotLands) {
  // Given an active session
  LinkPair link(Px4(), EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(5.0, Hover(), [&] { return link.session.active(); }));
  // When the autopilot's frames stop arriving (and ours stop reaching it)
  const double cut = link.t;
  link.downlink = false;
  link.uplink = false;
  link.RunUntil(cut + 3.0, Hover(), [] { return false; });
  // Then the session handed back for the lost stream, 0.2 s after the last frame (to the step)
  EXPECT_EQ(link.session.state(), SessionState::kHandedBack);
  EXPECT_EQ(link.session.reason(), SessionReason::kStateStreamLost);
  SessionEvent e, last;
  while (link.session.PopEvent(&e)) last = e;
  EXPECT_GT(last.time - cut, 0.2 - 0.05);
  EXPECT_LE(last.time - cut, 0.2 + 0.05 + 1e-9);
  // And PX4's setpoint-loss failsafe engaged 1 s after the last setpoint: it lands
  EXPECT_TRUE(link.autopilot.failsafe());
  EXPECT_EQ(link.autopilot.mode(), FlightMode::kLand);
  EXPECT_NEAR(link.autopilot.failsafe_time() - cut, 1.0, 0.1);
  EXPECT_FALSE(link.autopilot.Flying(link.t).valid());
}

TEST(SessionTest, HeartbeatLossHandsBackEvenWithTheStateStreamAlive) {
  LinkPair link(Px4(), EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(5.0, Hover(), [&] { return link.session.active(); }));
  link.heartbeats_down = false;
  link.RunUntil(link.t + 3.0, Hover(), [&] { return link.session.finished(); });
  EXPECT_EQ(link.session.reason(), SessionReason::kHeartbeatLost);
}

TEST(SessionTest, PilotChangingTheModeHandsBackAndTheSessionDoesNotRetakeControl) {
  LinkPair link(Px4(), EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(5.0, Hover(), [&] { return link.session.active(); }));
  link.RunUntil(link.t + 1.1, Hover(), [] { return false; });  // a HEARTBEAT shows OFFBOARD
  // When a ground station switches the vehicle to LAND
  mavlink::CommandLong land;
  land.command = mav::kCmdDoSetMode;
  land.target_system = 1;
  const SetModeParams p = SetModeParamsOf(AutopilotKind::kPx4, FlightMode::kLand);
  land.param1 = p.base_mode;
  land.param2 = p.custom_main;
  land.param3 = p.custom_sub;
  Outbox ignored;
  link.autopilot.OnFrame(testing::FrameOf(land, 255, 190), link.t, &ignored);
  link.RunUntil(link.t + 2.0, Hover(), [&] { return link.session.finished(); });
  // Then the session hands back for the mode change and sends no more setpoints or commands
  EXPECT_EQ(link.session.state(), SessionState::kHandedBack);
  EXPECT_EQ(link.session.reason(), SessionReason::kModeChanged);
  const long sp = link.setpoints_seen, cmds = link.commands_seen;
  link.RunUntil(link.t + 2.0, Hover(), [] { return false; });
  EXPECT_EQ(link.setpoints_seen, sp);
  EXPECT_EQ(link.commands_seen, cmds);
  EXPECT_EQ(link.autopilot.mode(), FlightMode::kLand);
}

TEST(SessionTest, UnansweredCommandsAreResentThenTheSessionFails) {
  // Given an autopilot that sends heartbeats but never receives our commands
  SessionSettings s = Px4();
  s.command_attempts = 3;
  LinkPair link(s, EmulatedPx4());
  link.uplink = false;
  link.RunUntil(10.0, Hover(), [&] { return link.session.finished(); });
  // Then the mode request went out three times, numbered 0, 1, 2, and the session failed
  EXPECT_EQ(link.session.state(), SessionState::kFailed);
  EXPECT_EQ(link.session.reason(), SessionReason::kCommandTimedOut);
  EXPECT_EQ(link.commands_seen, 3);
  EXPECT_EQ(link.last_confirmation, 2);
}

TEST(SessionTest, AnotherAutopilotThanConfiguredFailsAtTheFirstHeartbeat) {
  LinkPair link(Px4(), EmulatedArduPilot());
  link.RunUntil(3.0, Hover(), [&] { return link.session.finished(); });
  EXPECT_EQ(link.session.reason(), SessionReason::kWrongAutopilot);
  EXPECT_EQ(link.setpoints_seen, 0);
}

TEST(SessionTest, InvalidSetpointsAreNeverSent) {
  LinkPair link(Px4(), EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(5.0, Hover(), [&] { return link.session.active(); }));
  const long sent = link.setpoints_seen;
  for (const AttitudeSetpoint bad :
       {AttitudeSetpoint{kNaN, 0, 0, 0.5}, AttitudeSetpoint{0, 0, 0, 1.2},
        AttitudeSetpoint{0, 0, 0, -0.1}, AttitudeSetpoint{0, kInf, 0, 0.5}}) {
    link.Step(bad);
  }
  EXPECT_EQ(link.setpoints_seen, sent);
  EXPECT_EQ(link.session.skipped_setpoints(), 4);
  // The autopilot keeps flying the last valid one until its own timeout
  EXPECT_TRUE(link.autopilot.Flying(link.t).valid());
}

TEST(SessionTest, DisarmAfterLandingStreamsIdleUntilThePx4LandDetectorConfirms) {
  // Given an active session on the ground (the land detector sees no motion)
  LinkPair link(Px4(), EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(6.0, Hover(), [&] { return link.session.active(); }));
  // When the controller has landed and asks to disarm, still offering its hover setpoint
  const double landed = link.t;
  link.session.RequestDisarm(link.t);
  bool refused = false, idle_flown = false;
  ASSERT_TRUE(link.RunUntil(landed + 4.0, Hover(), [&] {
    double t = 0.0;
    refused = refused || link.autopilot.TakeEvent(&t) == EmulatorEvent::kDisarmRefused;
    const AttitudeSetpoint f = link.autopilot.Flying(link.t);
    idle_flown = idle_flown || (f.valid() && f.thrust == 0.0 && f.roll == 0.0 && f.pitch == 0.0);
    return link.session.finished();
  }));
  // Then PX4 first refused (not landed yet), the session streamed idle thrust level, and it
  // ended disarmed once the detector confirmed (0.6 s) and a HEARTBEAT showed it
  EXPECT_TRUE(refused);
  EXPECT_TRUE(idle_flown);
  EXPECT_EQ(link.session.state(), SessionState::kDisarmed);
  EXPECT_FALSE(link.autopilot.armed());
  EXPECT_GT(link.t - landed, 0.6 - 1e-9);
  EXPECT_LE(link.t - landed, 0.6 + 1.0 + 0.5 + 0.1);  // + a HEARTBEAT period + a resend
}

TEST(SessionTest, ArduPilotRefusesDisarmWithFailedUntilLandCompleteAndTheSessionRetries) {
  LinkPair link(ArduPilot(), EmulatedArduPilot());
  ASSERT_TRUE(link.RunUntil(6.0, Hover(), [&] { return link.session.active(); }));
  const double landed = link.t;
  link.session.RequestDisarm(link.t);
  ASSERT_TRUE(link.RunUntil(landed + 5.0, Hover(), [&] { return link.session.finished(); }));
  EXPECT_EQ(link.session.state(), SessionState::kDisarmed);
  EXPECT_GT(link.t - landed, 1.0 - 1e-9);  // LAND_DETECTOR_TRIGGER_SEC
  EXPECT_GT(link.commands_seen, 3);        // refused DISARMs were resent
}

TEST(SessionTest, AVehicleStillMovingIsNeverDisarmedAndTheSessionHandsBackAfterTheTimeout) {
  SessionSettings s = Px4();
  s.disarm_timeout = 3.0;
  LinkPair link(s, EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(6.0, Hover(), [&] { return link.session.active(); }));
  link.motion.vertical_speed = -0.5;  // still sinking: no ground contact
  const double landed = link.t;
  link.session.RequestDisarm(link.t);
  link.RunUntil(landed + 6.0, Hover(), [&] { return link.session.finished(); });
  EXPECT_TRUE(link.autopilot.armed());
  EXPECT_EQ(link.session.state(), SessionState::kHandedBack);
  EXPECT_EQ(link.session.reason(), SessionReason::kDisarmRefused);
  EXPECT_NEAR(link.t - landed, 3.0, 0.1);
}

TEST(SessionTest, TheMocapBridgeOnTheVehiclesSystemIdDoesNotFeedTheStateWatchdog) {
  // Given an active session
  LinkPair link(Px4(), EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(6.0, Hover(), [&] { return link.session.active(); }));
  // When the flight controller falls silent while a bridge (component 197) keeps talking
  link.downlink = false;
  const double cut = link.t;
  while (!link.session.finished() && link.t < cut + 2.0) {
    link.session.OnFrame(testing::FrameOf(mavlink::Odometry{}, 1, 197), link.t);
    link.session.OnFrame(testing::FrameOf(mavlink::Heartbeat{}, 1, 197), link.t);
    link.Step(Hover());
  }
  // Then the session hands back for the lost state stream within 0.25 s
  EXPECT_EQ(link.session.reason(), SessionReason::kStateStreamLost);
  EXPECT_LE(link.t - cut, 0.25 + 0.05);
}

TEST(SessionTest, AnAckForAnotherComponentIsIgnored) {
  // Given a session requesting OFFBOARD from an autopilot that hears nothing
  LinkPair link(Px4(), EmulatedPx4());
  link.uplink = false;
  link.RunUntil(3.0, Hover(),
                [&] { return link.session.state() == SessionState::kRequestingMode; });
  // When a DENIED for the same command arrives addressed to component 240
  mavlink::CommandAck ack;
  ack.command = mav::kCmdDoSetMode;
  ack.result = mav::kResultDenied;
  ack.target_system = 1;
  ack.target_component = 240;
  link.session.OnFrame(testing::FrameOf(ack, 1, 1), link.t);
  link.Step(Hover());
  // Then the session goes on
  EXPECT_EQ(link.session.state(), SessionState::kRequestingMode);
  // And the same ACK addressed to us ends it
  ack.target_component = 191;
  link.session.OnFrame(testing::FrameOf(ack, 1, 1), link.t);
  link.Step(Hover());
  EXPECT_EQ(link.session.state(), SessionState::kFailed);
}

TEST(SessionTest, AnAcceptedModeIsBelievedOnlyFromTheHeartbeat) {
  // Given PX4 accepting OFFBOARD, after which the pilot switches back before its HEARTBEAT
  LinkPair link(Px4(), EmulatedPx4());
  ASSERT_TRUE(
      link.RunUntil(4.0, Hover(), [&] { return link.autopilot.mode() == FlightMode::kOffboard; }));
  link.autopilot.SelectMode(FlightMode::kOther, link.t);
  const double switched = link.t;
  link.RunUntil(switched + 3.0, Hover(), [&] { return link.session.finished(); });
  // Then the session was never active, handed back for the mode change within a HEARTBEAT
  // period (+ 0.2 s), and the vehicle was never armed
  EXPECT_EQ(link.session.state(), SessionState::kHandedBack);
  EXPECT_EQ(link.session.reason(), SessionReason::kModeChanged);
  EXPECT_LE(link.t - switched, 1.0 + 0.2);
  EXPECT_FALSE(link.autopilot.armed());
  SessionEvent e;
  while (link.session.PopEvent(&e)) EXPECT_NE(e.state, SessionState::kActive);
}

TEST(SessionTest, PilotTakeoverWhileArmingHandsBackWithinAHeartbeat) {
  LinkPair link(Px4(), EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(5.0, Hover(), [&] { return link.autopilot.armed(); }));
  link.autopilot.SelectMode(FlightMode::kOther, link.t);
  const double switched = link.t;
  link.RunUntil(switched + 3.0, Hover(), [&] { return link.session.finished(); });
  EXPECT_EQ(link.session.reason(), SessionReason::kModeChanged);
  EXPECT_LE(link.t - switched, 1.0 + 0.2);
}

TEST(SessionTest, ALateFirstHeartbeatStillMakesTheHandshakeInTime) {
  // Given PX4's telemetry from t = 0 and its first HEARTBEAT only at 0.95 s
  LinkPair link(Px4(), EmulatedPx4());
  link.first_heartbeat_after = 0.95;
  // When the session runs: the warm-up started with the first frame
  ASSERT_TRUE(link.RunUntil(10.0, Hover(), [&] { return link.session.active(); }));
  // Then it is active within the handshake allowance
  EXPECT_LE(link.t, link.session.settings().handshake_time);
}

TEST(SessionTest, OneLostCommandIsResentAndTheHandshakeStillCompletesInTime) {
  LinkPair link(Px4(), EmulatedPx4());
  link.drop_commands = 1;  // the first mode request is lost
  ASSERT_TRUE(link.RunUntil(10.0, Hover(), [&] { return link.session.active(); }));
  EXPECT_GE(link.commands_seen, 3);  // mode twice, arm
  EXPECT_LE(link.t, link.session.settings().handshake_time);
}

TEST(SessionTest, TheImuStreamIsRequestedDuringTheWarmUpAndARefusalIsNotFatal) {
  // Given a session that wants the IMU at 250 Hz, against PX4 (grants it) and an ArduPilot
  // emulation that refuses (here: an autopilot answering DENIED to every stream request)
  SessionSettings s = Px4();
  s.imu_rate = 250.0;
  LinkPair link(s, EmulatedPx4());
  ASSERT_TRUE(link.RunUntil(6.0, Hover(), [&] { return link.session.active(); }));
  EXPECT_EQ(link.autopilot.StreamRate(SensorKind::kImu), 250.0);
  bool answered = false;
  SessionEvent e;
  while (link.session.PopEvent(&e)) {
    if (e.reason == SessionReason::kStreamRequest) {
      answered = true;
      EXPECT_EQ(e.command, mav::kCmdSetMessageInterval);
      EXPECT_EQ(e.result, mav::kResultAccepted);
      EXPECT_EQ(e.state, SessionState::kWarmingUp);
    }
  }
  EXPECT_TRUE(answered);
  // An autopilot that never answers the request: the handshake goes on after the warm-up
  SessionSettings q = Px4();
  q.imu_rate = 250.0;
  LinkPair silent(q, EmulatedPx4());
  silent.drop_commands = 1000;  // every command lost...
  silent.RunUntil(1.6, Hover(), [] { return false; });
  silent.drop_commands = 0;  // ...until the warm-up ends
  ASSERT_TRUE(silent.RunUntil(8.0, Hover(), [&] { return silent.session.active(); }));
}

TEST(SessionTest, InvalidSettingsNameTheField) {
  SessionSettings s;
  s.state_timeout = -1.0;
  try {
    AutopilotSession session(s);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("state_timeout"), std::string::npos) << e.what();
  }
  s = SessionSettings{};
  s.heartbeat_timeout = 0.5;  // shorter than a 1 Hz heartbeat's period
  EXPECT_THROW(AutopilotSession{s}, std::invalid_argument);
  EXPECT_THROW(ParseAutopilotKind("px5"), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::autopilot

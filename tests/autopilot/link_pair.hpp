// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/autopilot/emulated_autopilot.hpp"
#include "fnmpc/autopilot/session.hpp"

/// A session and an emulated autopilot wired back to back in memory (no encoding: the
/// frames carry the messages and the senders' ids), with switches to cut either direction.
namespace fnmpc::autopilot::testing {

inline mavlink::Frame FrameOf(const mavlink::Message& m, int system, int component) {
  mavlink::Frame f;
  f.header.system_id = static_cast<std::uint8_t>(system);
  f.header.component_id = static_cast<std::uint8_t>(component);
  f.header.message_id = mavlink::InfoOf(m).id;
  f.message = m;
  return f;
}

struct LinkPair {
  explicit LinkPair(const SessionSettings& s, const EmulatedAutopilotSettings& e)
      : session(s), autopilot(e) {}
  AutopilotSession session;
  EmulatedAutopilot autopilot;
  bool uplink = true;    // session -> autopilot delivered
  bool downlink = true;  // autopilot -> session delivered
  bool heartbeats_down = true;
  double first_heartbeat_after = 0.0;  // HEARTBEATs before this time [s] are lost
  LandDetectorInput motion;            // what the autopilot's land detector sees
  int drop_commands = 0;               // the next this many COMMAND_LONGs are lost
  long setpoints_seen = 0;             // SET_ATTITUDE_TARGET in the session's outboxes
  long commands_seen = 0;
  int last_confirmation = -1;
  double t = 0.0;

  /// One control step of `dt` with `setpoint`: the autopilot's messages to the session,
  /// then the session's to the autopilot.
  void Step(const AttitudeSetpoint& setpoint, double dt = 0.05) {
    Outbox down, up, acks;
    autopilot.Step(t, &down, motion);
    // A state stream: the autopilot's attitude at each step.
    down.Push(mavlink::Attitude{});
    for (const mavlink::Message& m : down) {
      const bool hb = std::holds_alternative<mavlink::Heartbeat>(m);
      const bool hb_lost = hb && (!heartbeats_down || t < first_heartbeat_after);
      if (downlink && !hb_lost) session.OnFrame(FrameOf(m, 1, 1), t);
    }
    session.Step(t, setpoint, static_cast<std::uint32_t>(t * 1000.0), &up);
    for (const mavlink::Message& m : up) {
      if (std::holds_alternative<mavlink::SetAttitudeTarget>(m)) ++setpoints_seen;
      if (const auto* c = std::get_if<mavlink::CommandLong>(&m)) {
        ++commands_seen;
        last_confirmation = c->confirmation;
        if (drop_commands > 0) {
          --drop_commands;
          continue;
        }
      }
      if (uplink) autopilot.OnFrame(FrameOf(m, 1, 191), t, &acks);
    }
    for (const mavlink::Message& m : acks) {
      if (downlink) session.OnFrame(FrameOf(m, 1, 1), t);
    }
    t += dt;
  }
  /// Steps until `until` [s] or the predicate holds; returns whether it held.
  template <class P>
  bool RunUntil(double until, const AttitudeSetpoint& sp, P&& done) {
    while (t < until) {
      Step(sp);
      if (done()) return true;
    }
    return false;
  }
};

inline AttitudeSetpoint Hover() { return {0.02, -0.01, 0.3, 0.45}; }

}  // namespace fnmpc::autopilot::testing

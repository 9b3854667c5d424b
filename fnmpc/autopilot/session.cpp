// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/autopilot/session.hpp"

#include <algorithm>
#include <cmath>
#include <variant>

namespace fnmpc::autopilot {

void SessionSettings::Validate() const {
  SessionSettings copy = *this;
  CheckLimits(copy, "SessionSettings");
}

std::string_view ToString(SessionState state) {
  switch (state) {
    case SessionState::kWaitingForAutopilot:
      return "waiting_for_autopilot";
    case SessionState::kWarmingUp:
      return "warming_up";
    case SessionState::kRequestingMode:
      return "requesting_mode";
    case SessionState::kArming:
      return "arming";
    case SessionState::kActive:
      return "active";
    case SessionState::kDisarming:
      return "disarming";
    case SessionState::kDisarmed:
      return "disarmed";
    case SessionState::kHandedBack:
      return "handed_back";
    case SessionState::kFailed:
      return "failed";
  }
  return "?";
}

std::string_view ToString(SessionReason reason) {
  switch (reason) {
    case SessionReason::kNone:
      return "none";
    case SessionReason::kStateStreamLost:
      return "state_stream_lost";
    case SessionReason::kHeartbeatLost:
      return "heartbeat_lost";
    case SessionReason::kModeChanged:
      return "mode_changed";
    case SessionReason::kDisarmedByAutopilot:
      return "disarmed_by_autopilot";
    case SessionReason::kCommandRejected:
      return "command_rejected";
    case SessionReason::kCommandTimedOut:
      return "command_timed_out";
    case SessionReason::kWrongAutopilot:
      return "wrong_autopilot";
    case SessionReason::kRequested:
      return "requested";
  }
  return "?";
}

AutopilotSession::AutopilotSession(const SessionSettings& settings) : settings_(settings) {
  settings_.Validate();
}

bool AutopilotSession::streaming() const {
  return state_ >= SessionState::kWarmingUp && state_ <= SessionState::kActive;
}

bool AutopilotSession::finished() const {
  return state_ == SessionState::kDisarmed || state_ == SessionState::kHandedBack ||
         state_ == SessionState::kFailed;
}

void AutopilotSession::Enter(double now, SessionState state, SessionReason reason,
                             std::uint16_t command, int result) {
  state_ = state;
  reason_ = reason;
  pending_.active = false;
  SessionEvent& e = events_[(event_head_ + event_count_) % events_.size()];
  e = SessionEvent{now, state, reason, command, result};
  if (event_count_ < events_.size()) {
    ++event_count_;
  } else {
    event_head_ = (event_head_ + 1) % events_.size();
  }
}

bool AutopilotSession::PopEvent(SessionEvent* event) {
  if (event_count_ == 0) return false;
  *event = events_[event_head_];
  event_head_ = (event_head_ + 1) % events_.size();
  --event_count_;
  return true;
}

void AutopilotSession::OnFrame(const mavlink::Frame& frame, double now) {
  if (frame.header.system_id != settings_.target_system || finished()) return;
  last_frame_ = now;
  if (const auto* hb = std::get_if<mavlink::Heartbeat>(&frame.message)) {
    if (frame.header.component_id != settings_.target_component) return;
    const std::uint8_t expected = settings_.autopilot == AutopilotKind::kPx4
                                      ? mav::kAutopilotPx4
                                      : mav::kAutopilotArduPilotMega;
    if (hb->autopilot != expected) {
      Enter(now, SessionState::kFailed, SessionReason::kWrongAutopilot);
      return;
    }
    heard_ = true;
    last_heartbeat_ = now;
    mode_ = ModeOf(settings_.autopilot, hb->custom_mode);
    armed_ = (hb->base_mode & mav::kModeFlagSafetyArmed) != 0;
    if (state_ >= SessionState::kRequestingMode && mode_ == FlightMode::kOffboard) {
      seen_active_mode_ = true;
    }
    if (state_ >= SessionState::kRequestingMode && armed_) seen_armed_ = true;
    if (state_ == SessionState::kDisarming && !armed_) seen_disarmed_ = true;
    if (state_ == SessionState::kWaitingForAutopilot) {
      warmup_start_ = now;
      Enter(now, SessionState::kWarmingUp, SessionReason::kNone);
    }
    return;
  }
  if (const auto* ack = std::get_if<mavlink::CommandAck>(&frame.message)) OnAck(*ack, now);
}

void AutopilotSession::OnAck(const mavlink::CommandAck& ack, double now) {
  if (!pending_.active || ack.command != pending_.command.command) return;
  // An ACK addressed to another system is not ours (fields 0: a sender that omits them).
  if (ack.target_system != 0 && ack.target_system != settings_.system_id) return;
  (void)now;
  ack_received_ = true;
  last_ack_result_ = ack.result;
}

void AutopilotSession::SendCommand(double now, std::uint16_t command, float p1, float p2, float p3,
                                   Outbox* out) {
  if (!pending_.active || pending_.command.command != command) {
    pending_ = Pending{};
    pending_.active = true;
    pending_.command.command = command;
    pending_.command.target_system = static_cast<std::uint8_t>(settings_.target_system);
    pending_.command.target_component = static_cast<std::uint8_t>(settings_.target_component);
    pending_.command.param1 = p1;
    pending_.command.param2 = p2;
    pending_.command.param3 = p3;
  } else {
    pending_.command.confirmation =
        static_cast<std::uint8_t>(std::min(pending_.sends, 255));  // resend count
  }
  ack_received_ = false;
  pending_.sent = now;
  ++pending_.sends;
  out->Push(pending_.command);
}

void AutopilotSession::HandBack(double now, SessionReason reason) {
  if (finished()) return;
  Enter(now, SessionState::kHandedBack, reason);
}

void AutopilotSession::RequestDisarm(double now) {
  if (state_ != SessionState::kActive) return;
  Enter(now, SessionState::kDisarming, SessionReason::kNone);
}

void AutopilotSession::Watchdogs(double now) {
  if (state_ < SessionState::kWarmingUp || finished()) return;
  if (now - last_frame_ > settings_.state_timeout) {
    HandBack(now, SessionReason::kStateStreamLost);
  } else if (now - last_heartbeat_ > settings_.heartbeat_timeout) {
    HandBack(now, SessionReason::kHeartbeatLost);
  } else if (state_ == SessionState::kActive && seen_active_mode_ &&
             mode_ != FlightMode::kOffboard) {
    HandBack(now, SessionReason::kModeChanged);
  } else if (state_ == SessionState::kActive && seen_armed_ && !armed_) {
    HandBack(now, SessionReason::kDisarmedByAutopilot);
  }
}

void AutopilotSession::Handshake(double now, Outbox* out) {
  // The answer to the pending command, if any.
  const std::uint16_t cmd = pending_.active ? pending_.command.command : 0;
  if (pending_.active && ack_received_) {
    ack_received_ = false;
    const std::uint8_t r = last_ack_result_;
    if (r == mav::kResultInProgress) {
      pending_.sent = now;  // still working: wait another timeout
    } else if (r == mav::kResultTemporarilyRejected) {
      // Retried at the next timeout (below), while sends remain.
    } else if (r != mav::kResultAccepted) {
      Enter(now, SessionState::kFailed, SessionReason::kCommandRejected, cmd, r);
      return;
    } else {
      pending_.active = false;
      switch (state_) {
        case SessionState::kRequestingMode:
          Enter(now, armed_ ? SessionState::kActive : SessionState::kArming, SessionReason::kNone,
                cmd, r);
          return;
        case SessionState::kArming:
          Enter(now, SessionState::kActive, SessionReason::kNone, cmd, r);
          return;
        case SessionState::kDisarming:
          Enter(now, SessionState::kDisarmed, SessionReason::kNone, cmd, r);
          return;
        default:
          return;
      }
    }
  }
  // What the HEARTBEAT shows counts as done too (an ACK may be lost).
  if (state_ == SessionState::kRequestingMode && mode_ == FlightMode::kOffboard &&
      seen_active_mode_) {
    Enter(now, armed_ ? SessionState::kActive : SessionState::kArming, SessionReason::kNone);
    return;
  }
  if (state_ == SessionState::kArming && armed_ && seen_armed_) {
    Enter(now, SessionState::kActive, SessionReason::kNone);
    return;
  }
  if (state_ == SessionState::kDisarming && seen_disarmed_) {
    Enter(now, SessionState::kDisarmed, SessionReason::kNone);
    return;
  }
  // The next send of the state's command: first, or after a timeout.
  std::uint16_t want = 0;
  float p1 = 0.0F, p2 = 0.0F, p3 = 0.0F;
  switch (state_) {
    case SessionState::kWarmingUp:
      if (now - warmup_start_ >= settings_.warmup - 1e-9) {
        Enter(now, SessionState::kRequestingMode, SessionReason::kNone);
        seen_active_mode_ = false;
        Handshake(now, out);
      }
      return;
    case SessionState::kRequestingMode: {
      const SetModeParams m = SetModeParamsOf(settings_.autopilot, FlightMode::kOffboard);
      want = mav::kCmdDoSetMode;
      p1 = m.base_mode;
      p2 = m.custom_main;
      p3 = m.custom_sub;
      break;
    }
    case SessionState::kArming:
      if (!settings_.arm) return;  // the pilot arms
      want = mav::kCmdComponentArmDisarm;
      p1 = 1.0F;
      break;
    case SessionState::kDisarming:
      want = mav::kCmdComponentArmDisarm;
      p1 = 0.0F;
      break;
    default:
      return;
  }
  if (pending_.active && pending_.command.command == want &&
      now - pending_.sent < settings_.command_timeout - 1e-9) {
    return;  // waiting for the answer
  }
  if (pending_.active && pending_.command.command == want &&
      pending_.sends >= settings_.command_attempts) {
    Enter(now, SessionState::kFailed, SessionReason::kCommandTimedOut, want,
          ack_received_ ? last_ack_result_ : -1);
    return;
  }
  SendCommand(now, want, p1, p2, p3, out);
}

void AutopilotSession::Step(double now, const AttitudeSetpoint& setpoint,
                            std::uint32_t time_boot_ms, Outbox* out) {
  if (!(now - last_own_heartbeat_ < settings_.heartbeat_period)) {
    mavlink::Heartbeat hb;
    hb.type = mav::kTypeOnboardController;
    hb.autopilot = mav::kAutopilotInvalid;
    hb.system_status = finished() ? mav::kStateStandby : mav::kStateActive;
    hb.mavlink_version = 3;
    out->Push(hb);
    last_own_heartbeat_ = now;
  }
  Watchdogs(now);
  Handshake(now, out);
  if (!streaming()) return;
  if (!setpoint.valid()) {
    ++skipped_;
    return;
  }
  out->Push(ToSetAttitudeTarget(setpoint, time_boot_ms,
                                static_cast<std::uint8_t>(settings_.target_system),
                                static_cast<std::uint8_t>(settings_.target_component)));
  ++sent_;
}

}  // namespace fnmpc::autopilot

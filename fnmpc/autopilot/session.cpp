// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/autopilot/session.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <variant>

namespace fnmpc::autopilot {

void SessionSettings::Validate() const {
  SessionSettings copy = *this;
  CheckLimits(copy, "SessionSettings");
  if (handshake_time < warmup + 1.0) {
    throw std::invalid_argument(
        "[SessionSettings] handshake_time must be at least warmup + 1 s (the mode request and "
        "arming after the warm-up)");
  }
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
    case SessionReason::kDisarmRefused:
      return "disarm_refused";
    case SessionReason::kStreamRequest:
      return "stream_request";
  }
  return "?";
}

AutopilotSession::AutopilotSession(const SessionSettings& settings) : settings_(settings) {
  settings_.Validate();
}

bool AutopilotSession::streaming() const {
  return state_ >= SessionState::kWarmingUp && state_ <= SessionState::kDisarming;
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
  LogEvent(now, reason, command, result);
}

void AutopilotSession::LogEvent(double now, SessionReason reason, std::uint16_t command,
                                int result) {
  SessionEvent& e = events_[(event_head_ + event_count_) % events_.size()];
  e = SessionEvent{now, state_, reason, command, result};
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
  // Only the flight controller itself: a motion-capture bridge or a camera on the same
  // system id must not keep its watchdogs alive or answer its commands.
  if (frame.header.system_id != settings_.target_system ||
      frame.header.component_id != settings_.target_component || finished()) {
    return;
  }
  last_frame_ = now;
  if (state_ == SessionState::kWaitingForAutopilot) {
    // Setpoints may stream before the first HEARTBEAT (autopilots send it at 1 Hz, their
    // telemetry at tens of Hz); the mode request waits for it.
    warmup_start_ = now;
    Enter(now, SessionState::kWarmingUp, SessionReason::kNone);
  }
  if (const auto* hb = std::get_if<mavlink::Heartbeat>(&frame.message)) {
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
    const bool in_mode = mode_ == FlightMode::kOffboard;
    if (state_ >= SessionState::kRequestingMode && in_mode) seen_active_mode_ = true;
    if (state_ >= SessionState::kRequestingMode && armed_ && seen_active_mode_) {
      seen_armed_ = true;
    }
    if (state_ == SessionState::kDisarming && !armed_) seen_disarmed_ = true;
    // A HEARTBEAT after an accepted command that does not show it: someone else (the pilot,
    // the autopilot's failsafe) changed the mode or the arming in between; never fight them.
    if ((mode_accepted_ && !in_mode) || (arm_accepted_ && !armed_)) contradicted_ = true;
    return;
  }
  if (const auto* ack = std::get_if<mavlink::CommandAck>(&frame.message)) OnAck(*ack, now);
}

void AutopilotSession::OnAck(const mavlink::CommandAck& ack, double now) {
  if (!pending_.active || ack.command != pending_.command.command) return;
  // Addressed to another system or component: not ours (0: a sender that omits them).
  if (ack.target_system != 0 && ack.target_system != settings_.system_id) return;
  if (ack.target_component != 0 && ack.target_component != settings_.component_id) return;
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
  disarm_start_ = now;
  seen_disarmed_ = false;
  Enter(now, SessionState::kDisarming, SessionReason::kNone);
}

void AutopilotSession::Watchdogs(double now) {
  if (state_ < SessionState::kWarmingUp || finished()) return;
  const double heartbeat_reference = heard_ ? last_heartbeat_ : warmup_start_;
  const bool mode_confirmed = seen_active_mode_ && state_ >= SessionState::kArming;
  if (now - last_frame_ > settings_.state_timeout) {
    HandBack(now, SessionReason::kStateStreamLost);
  } else if (now - heartbeat_reference > settings_.heartbeat_timeout) {
    HandBack(now, SessionReason::kHeartbeatLost);
  } else if (state_ == SessionState::kDisarming && seen_disarmed_) {
    return;  // done: the handshake ends the session disarmed
  } else if (contradicted_ && (mode_accepted_ || mode_confirmed) &&
             mode_ != FlightMode::kOffboard) {
    HandBack(now, SessionReason::kModeChanged);
  } else if (mode_confirmed && mode_ != FlightMode::kOffboard) {
    HandBack(now, SessionReason::kModeChanged);
  } else if (contradicted_ && !armed_) {
    HandBack(now, SessionReason::kDisarmedByAutopilot);
  } else if (state_ == SessionState::kActive && seen_armed_ && !armed_) {
    HandBack(now, SessionReason::kDisarmedByAutopilot);
  } else if (state_ == SessionState::kDisarming && now - disarm_start_ > settings_.disarm_timeout) {
    HandBack(now, SessionReason::kDisarmRefused);
  }
}

double AutopilotSession::ResendAfter() const {
  // Back-off for lost ACKs: each resend waits half a timeout longer than the one before.
  return settings_.command_timeout * (1.0 + 0.5 * std::max(0, pending_.sends - 1));
}

void AutopilotSession::Handshake(double now, Outbox* out) {
  // The answer to the pending command, if any.
  const std::uint16_t cmd = pending_.active ? pending_.command.command : 0;
  if (pending_.active && ack_received_) {
    ack_received_ = false;
    const std::uint8_t r = last_ack_result_;
    if (state_ == SessionState::kWarmingUp) {
      // The stream request's answer, whatever it is: logged, the warm-up goes on.
      stream_requested_ = true;
      pending_.active = false;
      LogEvent(now, SessionReason::kStreamRequest, cmd, r);
    } else if (state_ == SessionState::kDisarming) {
      // Refused while the land detector has not confirmed (PX4 TEMPORARILY_REJECTED,
      // ArduPilot FAILED), or accepted: resent at the next timeout until a HEARTBEAT shows
      // the vehicle disarmed or disarm_timeout passes.
    } else if (r == mav::kResultInProgress) {
      pending_.sent = now;  // still working: wait another timeout
    } else if (r == mav::kResultTemporarilyRejected) {
      // Retried at the next timeout (below), while sends remain.
    } else if (r != mav::kResultAccepted) {
      Enter(now, SessionState::kFailed, SessionReason::kCommandRejected, cmd, r);
      return;
    } else {
      pending_.active = false;
      if (state_ == SessionState::kRequestingMode) mode_accepted_ = true;
      if (state_ == SessionState::kArming) arm_accepted_ = true;
      SessionEvent& e = last_event_of_ack_;
      e = SessionEvent{now, state_, SessionReason::kNone, cmd, r};
      has_ack_event_ = true;
    }
  }
  // Only a HEARTBEAT makes a step done: the mode, then armed in it, then disarmed.
  if (state_ == SessionState::kRequestingMode && seen_active_mode_) {
    const std::uint16_t c = has_ack_event_ ? last_event_of_ack_.command : 0;
    const int r = has_ack_event_ ? last_event_of_ack_.result : -1;
    has_ack_event_ = false;
    Enter(now, SessionState::kArming, SessionReason::kNone, c, r);
    if (!seen_armed_) return;
  }
  if (state_ == SessionState::kArming && seen_armed_ && mode_ == FlightMode::kOffboard) {
    const std::uint16_t c = has_ack_event_ ? last_event_of_ack_.command : 0;
    const int r = has_ack_event_ ? last_event_of_ack_.result : -1;
    has_ack_event_ = false;
    Enter(now, SessionState::kActive, SessionReason::kNone, c, r);
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
      if (heard_ && settings_.imu_rate > 0.0 && !stream_requested_) {
        want = mav::kCmdSetMessageInterval;
        if (pending_.active && pending_.command.command == want &&
            pending_.sends >= settings_.command_attempts &&
            now - pending_.sent >= ResendAfter() - 1e-9) {
          stream_requested_ = true;  // no answer: the estimators run on what arrives
          pending_.active = false;
          LogEvent(now, SessionReason::kStreamRequest, want, -1);
        } else if (!pending_.active || now - pending_.sent >= ResendAfter() - 1e-9) {
          // param1 HIGHRES_IMU (105), param2 the interval [us]
          SendCommand(now, want, 105.0F, static_cast<float>(1e6 / settings_.imu_rate), 0.0F, out);
        }
      }
      if (heard_ && now - warmup_start_ >= settings_.warmup - 1e-9) {
        Enter(now, SessionState::kRequestingMode, SessionReason::kNone);
        seen_active_mode_ = mode_ == FlightMode::kOffboard;
        Handshake(now, out);
      }
      return;
    case SessionState::kRequestingMode: {
      if (mode_accepted_) return;  // accepted: the next HEARTBEAT must show it
      const SetModeParams m = SetModeParamsOf(settings_.autopilot, FlightMode::kOffboard);
      want = mav::kCmdDoSetMode;
      p1 = m.base_mode;
      p2 = m.custom_main;
      p3 = m.custom_sub;
      break;
    }
    case SessionState::kArming:
      if (!settings_.arm || arm_accepted_) return;  // the pilot arms / waiting for HEARTBEAT
      want = mav::kCmdComponentArmDisarm;
      p1 = 1.0F;
      break;
    case SessionState::kDisarming:
      want = mav::kCmdComponentArmDisarm;
      p1 = 0.0F;
      if (pending_.active && pending_.command.command == want &&
          now - pending_.sent < settings_.command_timeout - 1e-9) {
        return;
      }
      SendCommand(now, want, p1, p2, p3, out);
      return;
    default:
      return;
  }
  if (pending_.active && pending_.command.command == want &&
      now - pending_.sent < ResendAfter() - 1e-9) {
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
  AttitudeSetpoint sp = setpoint;
  if (state_ == SessionState::kDisarming) {
    // On the ground: idle thrust and a level attitude until the autopilot's land detector
    // confirms (its thresholds need the thrust near its minimum and no rotation).
    sp = AttitudeSetpoint{0.0, 0.0, std::isfinite(last_yaw_) ? last_yaw_ : 0.0, 0.0};
  }
  if (!sp.valid()) {
    ++skipped_;
    return;
  }
  last_yaw_ = sp.yaw;
  out->Push(ToSetAttitudeTarget(sp, time_boot_ms,
                                static_cast<std::uint8_t>(settings_.target_system),
                                static_cast<std::uint8_t>(settings_.target_component)));
  ++sent_;
}

}  // namespace fnmpc::autopilot

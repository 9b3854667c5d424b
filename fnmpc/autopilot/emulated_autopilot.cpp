// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/autopilot/emulated_autopilot.hpp"

#include <algorithm>
#include <cmath>
#include <variant>

namespace fnmpc::autopilot {

std::string_view ToString(EmulatorEvent event) {
  switch (event) {
    case EmulatorEvent::kNone:
      return "none";
    case EmulatorEvent::kModeChanged:
      return "mode_changed";
    case EmulatorEvent::kModeRejected:
      return "mode_rejected";
    case EmulatorEvent::kArmed:
      return "armed";
    case EmulatorEvent::kArmRejected:
      return "arm_rejected";
    case EmulatorEvent::kDisarmed:
      return "disarmed";
    case EmulatorEvent::kSetpointLost:
      return "setpoint_lost";
    case EmulatorEvent::kUnknownCommand:
      return "unknown_command";
    case EmulatorEvent::kDisarmRefused:
      return "disarm_refused";
    case EmulatorEvent::kLandDisarmed:
      return "land_disarmed";
    case EmulatorEvent::kPilotMode:
      return "pilot_mode";
    case EmulatorEvent::kStreamRate:
      return "stream_rate";
  }
  return "?";
}

EmulatedAutopilot::EmulatedAutopilot(const EmulatedAutopilotSettings& settings)
    : settings_(settings), land_detector_(settings.autopilot, settings.land_detector) {
  CheckLimits(settings_, "EmulatedAutopilotSettings");
  const bool px4 = settings_.autopilot == AutopilotKind::kPx4;
  const auto rate = [](double set, double default_rate) { return set < 0.0 ? default_rate : set; };
  stream_rate_.fill(kInf);
  stream_rate_[static_cast<int>(SensorKind::kImu)] = rate(settings_.highres_imu_rate, px4 ? 50 : 0);
  stream_rate_[static_cast<int>(SensorKind::kCompass)] =
      rate(settings_.attitude_rate, px4 ? 100 : 50);
  stream_rate_[static_cast<int>(SensorKind::kBattery)] =
      rate(settings_.sys_status_rate, px4 ? 5 : 2);
  default_rate_ = stream_rate_;
  stream_next_.fill(-kInf);
}

namespace {
// The SensorKind a stream message carries (MAVLink id), or -1.
int KindOfMessage(float message_id) {
  if (message_id == 105.0F) return static_cast<int>(SensorKind::kImu);     // HIGHRES_IMU
  if (message_id == 30.0F) return static_cast<int>(SensorKind::kCompass);  // ATTITUDE
  if (message_id == 1.0F) return static_cast<int>(SensorKind::kBattery);   // SYS_STATUS
  return -1;
}
}  // namespace

bool EmulatedAutopilot::Streams(SensorKind kind, double stamp) {
  const int k = static_cast<int>(kind);
  const double rate = stream_rate_[k];
  if (std::isinf(rate)) return true;
  if (!(rate > 0.0)) return false;
  if (stamp < stream_next_[k] - 1e-6) return false;
  const double period = 1.0 / rate;
  // The next sample due one period after this one's slot (catching up after a gap).
  stream_next_[k] = std::isinf(stream_next_[k])
                        ? stamp + period
                        : std::max(stream_next_[k] + period, stamp + 0.5 * period);
  return true;
}

double EmulatedAutopilot::StreamRate(SensorKind kind) const {
  return stream_rate_[static_cast<int>(kind)];
}

void EmulatedAutopilot::Disarmed(double now, EmulatorEvent why) {
  armed_ = false;
  Note(why, now);
}

void EmulatedAutopilot::SelectMode(FlightMode mode, double now) {
  mode_ = mode;
  Note(EmulatorEvent::kPilotMode, now);
}

void EmulatedAutopilot::Note(EmulatorEvent e, double now) {
  event_ = e;
  event_time_ = now;
}

EmulatorEvent EmulatedAutopilot::TakeEvent(double* time) {
  const EmulatorEvent e = event_;
  if (time != nullptr) *time = event_time_;
  event_ = EmulatorEvent::kNone;
  return e;
}

bool EmulatedAutopilot::StreamAlive(double now) const {
  return std::isfinite(setpoint_time_) && now - setpoint_time_ <= 1.0 / settings_.min_setpoint_rate;
}

void EmulatedAutopilot::Ack(const mavlink::Frame& frame, std::uint16_t command, std::uint8_t result,
                            Outbox* out) {
  mavlink::CommandAck ack;
  ack.command = command;
  ack.result = result;
  ack.target_system = frame.header.system_id;
  ack.target_component = frame.header.component_id;
  out->Push(ack);
}

void EmulatedAutopilot::OnFrame(const mavlink::Frame& frame, double now, Outbox* out) {
  if (const auto* sp = std::get_if<mavlink::SetAttitudeTarget>(&frame.message)) {
    if (sp->target_system != settings_.system_id) return;
    const AttitudeSetpoint s = FromSetAttitudeTarget(*sp);
    if (!s.valid()) return;  // e.g. the lockstep's no-op answer (all fields ignored)
    if (!StreamAlive(now)) stream_start_ = now;
    setpoint_ = s;
    setpoint_time_ = now;
    return;
  }
  const auto* cmd = std::get_if<mavlink::CommandLong>(&frame.message);
  if (cmd == nullptr || cmd->target_system != settings_.system_id) return;
  if (cmd->command == mav::kCmdDoSetMode) {
    const FlightMode want =
        ModeOf(settings_.autopilot, SetModeParams{cmd->param1, cmd->param2, cmd->param3});
    bool ok = want != FlightMode::kOther && !failsafe_;
    // PX4 enters OFFBOARD only with a setpoint stream already running.
    if (ok && want == FlightMode::kOffboard && settings_.autopilot == AutopilotKind::kPx4) {
      ok = StreamAlive(now) && now - stream_start_ > settings_.offboard_warmup;
    }
    if (ok) {
      mode_ = want;
      Note(EmulatorEvent::kModeChanged, now);
    } else {
      Note(EmulatorEvent::kModeRejected, now);
    }
    Ack(frame, cmd->command,
        ok ? mav::kResultAccepted
           : (failsafe_ ? mav::kResultDenied : mav::kResultTemporarilyRejected),
        out);
    return;
  }
  if (cmd->command == mav::kCmdComponentArmDisarm) {
    if (cmd->param1 == 0.0F) {
      // Not forced (param2 21196 is the documented emergency force; we never send it).
      const bool forced = cmd->param2 == 21196.0F;
      if (armed_ && !forced && !land_detector_.disarm_allowed()) {
        // PX4 Commander: "Disarming denied: not landed" (TEMPORARILY_REJECTED); ArduPilot:
        // not land_complete (FAILED).
        Note(EmulatorEvent::kDisarmRefused, now);
        Ack(frame, cmd->command,
            settings_.autopilot == AutopilotKind::kPx4 ? mav::kResultTemporarilyRejected
                                                       : mav::kResultFailed,
            out);
        return;
      }
      if (armed_) Disarmed(now, EmulatorEvent::kDisarmed);
      Ack(frame, cmd->command, mav::kResultAccepted, out);
      return;
    }
    bool ok = mode_ == FlightMode::kOffboard && !failsafe_ && StreamAlive(now);
    if (settings_.autopilot == AutopilotKind::kArduPilot && (settings_.guid_options & 8) == 0) {
      ok = false;  // thrust would be read as a climb rate (docs/autopilot.md)
    }
    if (ok) {
      armed_ = true;
      land_detector_.Reset(now);
      Note(EmulatorEvent::kArmed, now);
    } else {
      Note(EmulatorEvent::kArmRejected, now);
    }
    Ack(frame, cmd->command, ok ? mav::kResultAccepted : mav::kResultDenied, out);
    return;
  }
  if (cmd->command == mav::kCmdSetMessageInterval) {
    // param1: message id; param2: interval [us], -1 stop, 0 the default. Both autopilots
    // answer it (PX4 mavlink_receiver, ArduPilot GCS_MAVLINK::handle_command_set_message_interval).
    const int k = KindOfMessage(cmd->param1);
    if (k < 0) {
      Ack(frame, cmd->command, mav::kResultDenied, out);
      return;
    }
    const float interval = cmd->param2;
    if (interval < 0.0F) {
      stream_rate_[k] = 0.0;
    } else if (interval == 0.0F) {
      stream_rate_[k] = default_rate_[k];
    } else {
      stream_rate_[k] = 1e6 / static_cast<double>(interval);
    }
    stream_next_[k] = -kInf;
    Note(EmulatorEvent::kStreamRate, now);
    Ack(frame, cmd->command, mav::kResultAccepted, out);
    return;
  }
  Note(EmulatorEvent::kUnknownCommand, now);
  Ack(frame, cmd->command, mav::kResultUnsupported, out);
}

void EmulatedAutopilot::Step(double now, Outbox* out, const LandDetectorInput& motion) {
  if (armed_ && mode_ == FlightMode::kOffboard && !failsafe_ &&
      !(now - setpoint_time_ <= settings_.setpoint_timeout)) {
    failsafe_ = true;
    failsafe_time_ = now;
    mode_ = FlightMode::kLand;
    Note(EmulatorEvent::kSetpointLost, now);
  }
  if (armed_) {
    LandDetectorInput in = motion;
    const AttitudeSetpoint flying = Flying(now);
    in.thrust = flying.valid() ? flying.thrust : kNaN;  // its own landing: the simulator's
    land_detector_.Update(now, in);
    if (land_detector_.auto_disarm_due(now)) Disarmed(now, EmulatorEvent::kLandDisarmed);
  }
  if (!(now - last_heartbeat_ < settings_.heartbeat_period)) {
    mavlink::Heartbeat hb;
    hb.custom_mode = CustomMode(settings_.autopilot, mode_);
    hb.type = mav::kTypeQuadrotor;
    hb.autopilot = settings_.autopilot == AutopilotKind::kPx4 ? mav::kAutopilotPx4
                                                              : mav::kAutopilotArduPilotMega;
    hb.base_mode = static_cast<std::uint8_t>(mav::kModeFlagCustomModeEnabled |
                                             (armed_ ? mav::kModeFlagSafetyArmed : 0));
    hb.system_status =
        failsafe_ ? mav::kStateCritical : (armed_ ? mav::kStateActive : mav::kStateStandby);
    hb.mavlink_version = 3;
    out->Push(hb);
    last_heartbeat_ = now;
  }
}

AttitudeSetpoint EmulatedAutopilot::Flying(double now) const {
  if (!armed_ || failsafe_ || mode_ != FlightMode::kOffboard ||
      !(now - setpoint_time_ <= settings_.setpoint_timeout)) {
    return {};
  }
  return setpoint_;
}

void EmulatedAutopilot::Disarm(double now) {
  if (!armed_) return;
  Disarmed(now, EmulatorEvent::kDisarmed);
}

}  // namespace fnmpc::autopilot

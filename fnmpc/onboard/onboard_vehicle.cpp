// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/onboard/onboard_vehicle.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <variant>

#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/formation/throttle_map.hpp"

namespace fnmpc::onboard {
namespace {

double StampOf(const mavlink::Message& m) {
  if (const auto* x = std::get_if<mavlink::HighresImu>(&m)) return x->time_usec * 1e-6;
  if (const auto* x = std::get_if<mavlink::Odometry>(&m)) return x->time_usec * 1e-6;
  if (const auto* x = std::get_if<mavlink::FnmpcRelativeObservation>(&m)) {
    return x->time_usec * 1e-6;
  }
  if (const auto* x = std::get_if<mavlink::AttitudeQuaternion>(&m)) return x->time_boot_ms * 1e-3;
  if (const auto* x = std::get_if<mavlink::Attitude>(&m)) return x->time_boot_ms * 1e-3;
  return kNaN;
}

}  // namespace

std::string_view ToString(OnboardStop stop) {
  switch (stop) {
    case OnboardStop::kNone:
      return "none";
    case OnboardStop::kDisarmed:
      return "disarmed";
    case OnboardStop::kSession:
      return "session";
    case OnboardStop::kNotReadyAtTakeoff:
      return "not_ready_at_takeoff";
  }
  return "?";
}

OnboardVehicle::OnboardVehicle(const formation::ControllerConfig& controller,
                               const autopilot::SessionSettings& session, OnboardClock clock)
    : controller_(controller),
      session_(session),
      clock_(clock),
      own_system_(static_cast<std::uint8_t>(session.target_system)) {
  const double ready = session.handshake_time;
  if (controller.takeoff_time < ready) {
    throw std::invalid_argument(
        "take-off at " + std::to_string(controller.takeoff_time) +
        " s leaves the autopilot handshake too little time: phases.takeoff_time must be >= " +
        std::to_string(ready) +
        " s (link handshake_time: the warm-up, the mode request and arming confirmed by the "
        "autopilot's 1 Hz HEARTBEATs)");
  }
}

bool OnboardVehicle::OnFrame(const mavlink::Frame& frame, double now) {
  session_.OnFrame(frame, now);
  if (frame.header.system_id != own_system_) return false;
  ++own_frames_;
  const double remote = StampOf(frame.message);
  double offset = 0.0;
  if (clock_ == OnboardClock::kLocal && std::isfinite(remote)) {
    autopilot::ClockMap& map = frame.header.component_id == session_.settings().target_component
                                   ? clock_map_
                                   : bridge_clock_map_;
    map.Observe(remote, now);
    // Never stamped after its arrival (the fitted line may pass a little above a sample).
    offset = std::min(map.ToLocal(remote), now) - remote;
  }
  if (clock_ == OnboardClock::kAutopilot &&
      std::holds_alternative<mavlink::AttitudeQuaternion>(frame.message)) {
    tick_time_ = remote;
    ++ticks_;
    return true;
  }
  Measurement m;
  if (autopilot::FromMessage(frame.message, controller_.config().vehicle, offset, now, &m)) {
    if (m.kind == SensorKind::kBattery) voltage_ = m.voltage;
    controller_.Process(m);
    ++measurements_;
    const int k = static_cast<int>(m.kind);
    if (kind_count_[k]++ == 0) kind_first_[k] = now;
    kind_last_[k] = now;
  }
  return false;
}

double OnboardVehicle::measured_rate(SensorKind kind) const {
  const int k = static_cast<int>(kind);
  if (kind_count_[k] < 2 || !(kind_last_[k] > kind_first_[k])) return kNaN;
  return static_cast<double>(kind_count_[k] - 1) / (kind_last_[k] - kind_first_[k]);
}

void OnboardVehicle::Stop(double t) {
  session_.HandBack(t);
  if (stop_ == OnboardStop::kNone) stop_ = OnboardStop::kSession;
}

const OnboardStep& OnboardVehicle::Step(double t, autopilot::Outbox* out) {
  OnboardStep& s = last_;
  s.control = controller_.Control(t);
  const formation::ControlOutput& c = s.control;
  if (c.phase != formation::FlightPhase::kIdle && c.phase != formation::FlightPhase::kLanded) {
    ++flight_steps_;
    if (!controller_.estimates().own.valid) ++unusable_steps_;
  }
  // The take-off gate: the PID must not climb while the autopilot is not flying our
  // setpoints (it would wind up, and the vehicle jump when armed late). Once flown, leaving
  // the active state (disarming after the landing, a hand-back) is the session's business.
  was_active_ = was_active_ || session_.active();
  if (stop_ == OnboardStop::kNone && !was_active_ && !session_.finished() &&
      c.phase != formation::FlightPhase::kIdle) {
    stop_ = OnboardStop::kNotReadyAtTakeoff;
    session_.HandBack(t);
  }
  // Normalised thrust: the controller's throttle (identified polynomial at its filtered
  // voltage), else the same map at the last voltage received; zero thrust is zero.
  double thrust = c.throttle;
  if (!std::isfinite(thrust)) {
    thrust = c.thrust == 0.0 ? 0.0
                             : formation::ThrustToThrottle(controller_.config().params.throttle,
                                                           c.thrust, voltage_);
  }
  s.setpoint = autopilot::AttitudeSetpoint{c.roll, c.pitch, c.yaw, thrust};
  if (c.phase == formation::FlightPhase::kLanded && session_.active()) {
    session_.RequestDisarm(t);
  }
  const long before = session_.setpoints_sent();
  const std::uint32_t ms =
      t >= 0.0 ? static_cast<std::uint32_t>(std::llround(t * 1000.0)) : std::uint32_t{0};
  session_.Step(t, s.setpoint, ms, out);
  s.sent = session_.setpoints_sent() > before;
  s.session = session_.state();
  if (clock_ == OnboardClock::kAutopilot && !s.sent) {
    mavlink::SetAttitudeTarget noop;  // the lockstep's answer to the tick: every field ignored
    noop.time_boot_ms = ms;
    noop.target_system = own_system_;
    noop.target_component = static_cast<std::uint8_t>(session_.settings().target_component);
    noop.type_mask = 0xFF;
    out->Push(noop);
  }
  if (stop_ == OnboardStop::kNone && session_.finished()) {
    stop_ = session_.state() == autopilot::SessionState::kDisarmed ? OnboardStop::kDisarmed
                                                                   : OnboardStop::kSession;
  }
  return s;
}

}  // namespace fnmpc::onboard

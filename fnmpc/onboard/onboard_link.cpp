// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/onboard/onboard_link.hpp"

#include <fmt/core.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/autopilot/measurement_messages.hpp"
#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/config/settings_yaml.hpp"
#include "fnmpc/link/link_address.hpp"
#include "fnmpc/link/mavlink_connection.hpp"
#include "fnmpc/link/signing_key.hpp"
#include "fnmpc/onboard/onboard_vehicle.hpp"

namespace fnmpc::onboard {
namespace {

autopilot::SessionSettings SessionSettingsFor(const OnboardLinkOptions& o, int vehicle,
                                              const formation::ControllerConfig& controller) {
  autopilot::SessionSettings s;
  // Ask for the IMU at the rate the estimator is set up for (a settings file may say
  // otherwise; 0: no request).
  if (controller.sensors.imu.enabled) s.imu_rate = controller.sensors.imu.rate_hz;
  if (!o.settings_file.empty()) {
    config::YamlMap map = config::YamlMap::LoadFile(o.settings_file);
    config::SettingsReader reader(&map);
    reader.Read(&s);
    reader.Finish();
    map.Finish();
  }
  s.autopilot = autopilot::ParseAutopilotKind(o.autopilot);
  // One MAVLink system per vehicle: vehicle i is system i + 1, flight controller and onboard
  // computer alike (PX4 MAV_SYS_ID, ArduPilot SYSID_THISMAV).
  s.target_system = autopilot::SystemIdOf(vehicle);
  s.system_id = s.target_system;
  return s;
}

formation::ControllerConfig WithReadyTakeoff(formation::ControllerConfig c, double ready) {
  if (c.takeoff_time < ready) c.takeoff_time = ready;
  return c;
}

nlohmann::json MeasurementRates(const OnboardVehicle& v) {
  nlohmann::json rates = nlohmann::json::object();
  for (int k = 0; k < kNumSensorKinds; ++k) {
    const auto kind = static_cast<SensorKind>(k);
    if (v.measurements(kind) == 0) continue;
    const double r = v.measured_rate(kind);
    rates[std::string(ToString(kind))] = std::isfinite(r) ? nlohmann::json(r) : nlohmann::json();
  }
  return rates;
}

}  // namespace

struct OnboardLink::Impl {
  Impl(const formation::ControllerConfig& c, int vehicle, const OnboardLinkOptions& o,
       const autopilot::SessionSettings& s)
      : settings(s),
        ready(s.handshake_time),
        scenario_takeoff(c.takeoff_time),
        conn(link::OpenTransport(link::ParseLinkAddress(o.link)),
             static_cast<std::uint8_t>(s.system_id), static_cast<std::uint8_t>(s.component_id)),
        onboard(WithReadyTakeoff(c, ready), s,
                o.autopilot_clock ? OnboardClock::kAutopilot : OnboardClock::kLocal),
        autopilot_clock(o.autopilot_clock) {
    (void)vehicle;
    if (!o.signing_key.empty()) conn.EnableSigning(link::ReadSigningKey(o.signing_key), 0);
    // Listen mode answers only the flight controller (never a bridge or junk on the port).
    conn.ExpectPeer(static_cast<std::uint8_t>(s.target_system),
                    static_cast<std::uint8_t>(s.target_component));
  }
  void Send() {
    for (const mavlink::Message& m : out) conn.Send(m);
    out.Clear();
  }
  autopilot::SessionSettings settings;
  double ready;
  double scenario_takeoff;
  link::MavlinkConnection conn;
  OnboardVehicle onboard;
  bool autopilot_clock;
  autopilot::Outbox out;
  const OnboardStep* last = nullptr;
};

OnboardLink::OnboardLink(formation::ControllerConfig controller, int vehicle,
                         const OnboardLinkOptions& options) {
  const autopilot::SessionSettings s = SessionSettingsFor(options, vehicle, controller);
  impl_ = std::make_unique<Impl>(controller, vehicle, options, s);
}

OnboardLink::~OnboardLink() = default;

bool OnboardLink::Poll(double timeout, double now) {
  return Poll(timeout, [now] { return now; });
}

bool OnboardLink::Poll(double timeout, const std::function<double()>& clock) {
  bool tick = false;
  impl_->conn.Poll(timeout, [&](const mavlink::Frame& f) {
    double at = clock();
    if (impl_->autopilot_clock) {
      const double t = impl_->onboard.tick_time();
      at = std::isfinite(t) ? t : 0.0;
    }
    tick = impl_->onboard.OnFrame(f, at) || tick;
  });
  return tick;
}

double OnboardLink::tick_time() const { return impl_->onboard.tick_time(); }
long OnboardLink::ticks() const { return impl_->onboard.ticks(); }
long OnboardLink::own_frames() const { return impl_->onboard.own_frames(); }

const formation::ControlOutput& OnboardLink::Step(double t) {
  impl_->last = &impl_->onboard.Step(t, &impl_->out);
  impl_->Send();
  impl_->onboard.Diagnose();
  return impl_->last->control;
}

bool OnboardLink::sent() const { return impl_->last != nullptr && impl_->last->sent; }
double OnboardLink::normalised_thrust() const {
  return impl_->last != nullptr ? impl_->last->setpoint.thrust : kNaN;
}

void OnboardLink::SayHello() {
  mavlink::Heartbeat hello;
  hello.type = autopilot::mav::kTypeOnboardController;
  hello.autopilot = autopilot::mav::kAutopilotInvalid;
  hello.mavlink_version = 3;
  impl_->conn.Send(hello);
}

void OnboardLink::Stop(double t) {
  impl_->onboard.Stop(t);
  impl_->last = &impl_->onboard.Step(t, &impl_->out);  // our HEARTBEAT says standby
  impl_->Send();
}

bool OnboardLink::stopped() const { return impl_->onboard.stop() != OnboardStop::kNone; }
bool OnboardLink::disarmed() const { return impl_->onboard.stop() == OnboardStop::kDisarmed; }
std::string OnboardLink::stop_reason() const {
  const OnboardStop s = impl_->onboard.stop();
  std::string r(ToString(s));
  if (s == OnboardStop::kSession) {
    r += fmt::format(" ({}, {})", autopilot::ToString(impl_->onboard.session().state()),
                     autopilot::ToString(impl_->onboard.session().reason()));
  }
  return r;
}
std::string OnboardLink::session_state() const {
  return std::string(autopilot::ToString(impl_->onboard.session().state()));
}

bool OnboardLink::PopEvent(std::string* line, nlohmann::json* event) {
  autopilot::SessionEvent e;
  if (!impl_->onboard.session().PopEvent(&e)) return false;
  *event = {{"t", e.time},
            {"state", autopilot::ToString(e.state)},
            {"reason", autopilot::ToString(e.reason)}};
  if (e.command != 0) (*event)["command"] = e.command;
  if (e.result >= 0) (*event)["result"] = e.result;
  *line = fmt::format("t = {:.2f} s: session {}", e.time, autopilot::ToString(e.state));
  if (e.reason != autopilot::SessionReason::kNone) {
    *line += fmt::format(" ({})", autopilot::ToString(e.reason));
  }
  if (e.command != 0) *line += fmt::format(", MAV_CMD {} result {}", e.command, e.result);
  return true;
}

double OnboardLink::ready_time() const { return impl_->ready; }
bool OnboardLink::moved_takeoff() const { return impl_->scenario_takeoff < impl_->ready; }
double OnboardLink::scenario_takeoff_time() const { return impl_->scenario_takeoff; }
int OnboardLink::system_id() const { return impl_->settings.system_id; }
std::string OnboardLink::describe() const { return impl_->conn.transport().Describe(); }
long OnboardLink::measurements() const { return impl_->onboard.measurements(); }
formation::VehicleController& OnboardLink::controller() { return impl_->onboard.controller(); }

nlohmann::json OnboardLink::Summary() const {
  const OnboardVehicle& v = impl_->onboard;
  const mavlink::ParserCounters& pc = impl_->conn.counters();
  return {{"autopilot", autopilot::ToString(impl_->settings.autopilot)},
          {"link", describe()},
          {"system_id", impl_->settings.system_id},
          {"stop", ToString(v.stop())},
          {"session_state", autopilot::ToString(v.session().state())},
          {"session_reason", autopilot::ToString(v.session().reason())},
          {"setpoints_sent", v.session().setpoints_sent()},
          {"setpoints_skipped", v.session().skipped_setpoints()},
          {"measurements", v.measurements()},
          {"measurement_rates_hz", MeasurementRates(v)},
          {"flight_steps", v.flight_steps()},
          {"unusable_estimate_steps", v.unusable_estimate_steps()},
          {"clock_rate", v.clock_map().rate()},
          {"link_signed", impl_->conn.signing()},
          {"clock_resets", v.clock_map().resets()},
          {"ticks", v.ticks()},
          {"final_phase", formation::ToString(v.controller().phase())},
          {"failsafe", v.controller().failsafe()},
          {"fallbacks", v.controller().fallbacks()},
          {"takeoff_time_s", v.controller().config().takeoff_time},
          {"link_counters",
           {{"frames_ok", pc.frames_ok},
            {"bytes_received", pc.bytes_received},
            {"bytes_discarded", pc.bytes_discarded},
            {"crc_errors", pc.crc_errors},
            {"unknown_ids", pc.unknown_ids},
            {"unknown_frames", pc.unknown_frames},
            {"bytes_in_unknown_frames", pc.bytes_in_unknown_frames},
            {"bad_lengths", pc.bad_lengths},
            {"signature_failures", pc.signature_failures},
            {"frames_sent", impl_->conn.frames_sent()},
            {"send_failures", impl_->conn.send_failures()}}}};
}

}  // namespace fnmpc::onboard

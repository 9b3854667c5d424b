// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "fnmpc/formation/vehicle_controller.hpp"

/// An onboard computer's link to its flight controller: the MAVLink connection
/// (fnmpc/link) around an OnboardVehicle (controller + autopilot session). What `fnmpc fly`
/// and the ROS vehicle node (parameter ~link) share; this header stays C++17 so the ROS
/// translation units can include it.
namespace fnmpc::onboard {

struct OnboardLinkOptions {
  std::string link;           ///< udp:HOST:PORT, udpout:HOST:PORT or serial:DEVICE:BAUD
  std::string autopilot;      ///< px4 or ardupilot
  std::string settings_file;  ///< YAML of autopilot::SessionSettings keys ("": defaults)
  /// The autopilot's clock (lockstep with `fnmpc sim-link --lockstep`), else the caller's.
  bool autopilot_clock = false;
  /// MAVLink 2 signing key file ("": unsigned; link::ReadSigningKey).
  std::string signing_key;
};

class OnboardLink {
 public:
  /// Vehicle `vehicle` of its scenario is MAVLink system vehicle + 1. A take-off earlier
  /// than the handshake allows is moved to ready_time() (moved_takeoff() says so). Throws
  /// std::invalid_argument (bad option, settings file) or std::runtime_error (the link).
  OnboardLink(formation::ControllerConfig controller, int vehicle,
              const OnboardLinkOptions& options);
  ~OnboardLink();
  OnboardLink(const OnboardLink&) = delete;
  OnboardLink& operator=(const OnboardLink&) = delete;

  /// Waits up to `timeout` [s] for the link and feeds what came (frames received at `now`,
  /// the caller's clock; with the autopilot's clock the last tick's time is used). Returns
  /// true when a control tick arrived (autopilot clock): call Step(tick_time()).
  bool Poll(double timeout, double now);
  /// The same, each frame stamped with `clock()` when it is handed over (after the wait, not
  /// before it: a frame that arrives during the wait gets its arrival time).
  bool Poll(double timeout, const std::function<double()>& clock);
  [[nodiscard]] double tick_time() const;
  [[nodiscard]] long ticks() const;
  /// Frames received from the vehicle's own autopilot (its system id).
  [[nodiscard]] long own_frames() const;
  /// One control step at `t`: controller, take-off gate, setpoint, session; sends what the
  /// session wants sent, then the step's diagnostics (KKT, cost). Returns the control output.
  const formation::ControlOutput& Step(double t);
  /// Whether the last step's setpoint was sent, and its normalised thrust.
  [[nodiscard]] bool sent() const;
  [[nodiscard]] double normalised_thrust() const;
  /// A HEARTBEAT now (before the first tick, so a listening endpoint learns our address).
  void SayHello();
  /// Stops commanding (the autopilot's failsafe takes over) and sends our standby HEARTBEAT.
  void Stop(double t);
  /// Stopped commanding (landed and disarmed, handed back, failed, not ready at take-off).
  [[nodiscard]] bool stopped() const;
  /// ... because it landed and disarmed.
  [[nodiscard]] bool disarmed() const;
  [[nodiscard]] std::string stop_reason() const;
  [[nodiscard]] std::string session_state() const;
  /// The next session event as a log line ("t = 1.05 s: session arming, MAV_CMD 176 result
  /// 0") and as JSON; false when none is left.
  bool PopEvent(std::string* line, nlohmann::json* event);
  [[nodiscard]] double ready_time() const;
  [[nodiscard]] bool moved_takeoff() const;
  [[nodiscard]] double scenario_takeoff_time() const;
  [[nodiscard]] int system_id() const;
  [[nodiscard]] std::string describe() const;  ///< the transport, e.g. "udpout:127.0.0.1:14600"
  [[nodiscard]] long measurements() const;
  /// Counters and states for the run's summary.
  [[nodiscard]] nlohmann::json Summary() const;
  formation::VehicleController& controller();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fnmpc::onboard

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include "fnmpc/autopilot/measurement_messages.hpp"
#include "fnmpc/autopilot/outbox.hpp"
#include "fnmpc/autopilot/session.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/mavlink/parser.hpp"

/// One vehicle's onboard computer without its I/O: the formation controller, the autopilot
/// session and what joins them (measurements from the link into the estimators, the
/// controller's command into normalised-thrust setpoints, the take-off gate). `fnmpc fly` and
/// the tests drive it; the wrapper does the sockets and the clock (PX4's split of module and
/// controller). No allocation per frame or step.
namespace fnmpc::onboard {

/// How the onboard computer tells the time.
enum class OnboardClock : int {
  /// Its own steady clock; the autopilot's stamps are mapped onto it (ClockMap: offset and
  /// rate). Flight.
  kLocal = 0,
  /// The autopilot's: each ATTITUDE_QUATERNION's time_boot_ms is a control tick, stamps are
  /// taken as they are, and every tick is answered with one SET_ATTITUDE_TARGET stamped
  /// with it (a no-op one, all fields ignored, when there is nothing to send). The lockstep
  /// of the simulator's endpoint (`fnmpc sim-link --lockstep`), as in PX4's SITL.
  kAutopilot = 1,
};

/// Why the onboard computer stopped commanding (kNone: it still does or never started).
enum class OnboardStop : int {
  kNone = 0,
  kDisarmed = 1,           ///< landed and disarmed: the flight is over
  kSession = 2,            ///< the session handed back or failed (AutopilotSession::reason)
  kNotReadyAtTakeoff = 3,  ///< the autopilot was not flying our setpoints at take-off time
};
std::string_view ToString(OnboardStop stop);

/// One control step, for the log.
struct OnboardStep {
  formation::ControlOutput control;
  autopilot::AttitudeSetpoint setpoint;  ///< what was offered to the session
  bool sent = false;                     ///< the session sent it
  autopilot::SessionState session = autopilot::SessionState::kWaitingForAutopilot;
};

class OnboardVehicle {
 public:
  /// `controller.takeoff_time` must leave the session time for its handshake (warm-up plus
  /// the session's handshake_time): throws std::invalid_argument naming both otherwise.
  OnboardVehicle(const formation::ControllerConfig& controller,
                 const autopilot::SessionSettings& session, OnboardClock clock);

  /// A frame from the link received at `now` (this computer's clock, [s]): to the session,
  /// and the flight controller's measurements to the estimators. In kAutopilot clock mode,
  /// returns true when the frame is a control tick (its time: tick_time()).
  bool OnFrame(const mavlink::Frame& frame, double now);
  /// One control step at `t` [s] (the local clock, or the tick's time): controller, take-off
  /// gate, setpoint, session; the messages to send go to `out`.
  const OnboardStep& Step(double t, autopilot::Outbox* out);
  /// The KKT value and cost of the last step's NMPC iterate into its log (after the
  /// command was sent: N more integrations).
  void Diagnose() { controller_.Diagnose(&last_.control); }
  /// Stops commanding now (operator, signal); the autopilot's failsafe takes over.
  void Stop(double t);

  [[nodiscard]] double tick_time() const { return tick_time_; }
  [[nodiscard]] OnboardStop stop() const { return stop_; }
  [[nodiscard]] const autopilot::AutopilotSession& session() const { return session_; }
  autopilot::AutopilotSession& session() { return session_; }
  [[nodiscard]] const formation::VehicleController& controller() const { return controller_; }
  formation::VehicleController& controller() { return controller_; }
  [[nodiscard]] long measurements() const { return measurements_; }
  [[nodiscard]] long ticks() const { return ticks_; }
  /// Frames received from our own system (the vehicle's autopilot).
  [[nodiscard]] long own_frames() const { return own_frames_; }
  /// Measurements of `kind` received, and their mean arrival rate [Hz] (NaN before two).
  [[nodiscard]] long measurements(SensorKind kind) const {
    return kind_count_[static_cast<int>(kind)];
  }
  [[nodiscard]] double measured_rate(SensorKind kind) const;
  /// Control steps in flight (take-off to landing, failsafe included) whose own-state
  /// estimate was not valid (VehicleEstimate::valid: stale, uncertain, not initialised).
  [[nodiscard]] long unusable_estimate_steps() const { return unusable_steps_; }
  /// Control steps in flight.
  [[nodiscard]] long flight_steps() const { return flight_steps_; }
  /// The flight controller's clock mapping (kLocal): local seconds per autopilot second.
  [[nodiscard]] const autopilot::ClockMap& clock_map() const { return clock_map_; }

 private:
  formation::VehicleController controller_;
  autopilot::AutopilotSession session_;
  OnboardClock clock_;
  // One clock per source: the flight controller's, and a bridge's (motion capture, relative
  // sensor: another component on the vehicle's system id, on a clock of its own).
  autopilot::ClockMap clock_map_, bridge_clock_map_;
  std::uint8_t own_system_;
  double tick_time_ = kNaN;
  double voltage_ = kNaN;
  OnboardStop stop_ = OnboardStop::kNone;
  bool was_active_ = false;  // the session has flown our setpoints (the take-off gate is past)
  OnboardStep last_;
  long measurements_ = 0, ticks_ = 0, own_frames_ = 0;
  long unusable_steps_ = 0, flight_steps_ = 0;
  std::array<long, kNumSensorKinds> kind_count_{};
  std::array<double, kNumSensorKinds> kind_first_{}, kind_last_{};
};

}  // namespace fnmpc::onboard

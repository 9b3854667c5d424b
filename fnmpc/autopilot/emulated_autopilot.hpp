// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>

#include "fnmpc/autopilot/land_detector.hpp"
#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/autopilot/outbox.hpp"
#include "fnmpc/autopilot/setpoint.hpp"
#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/mavlink/parser.hpp"

/// The flight-controller side of the link as the simulator's MAVLink endpoint plays it: the
/// mode switching, arming and setpoint-loss rules of PX4 (offboard) or ArduPilot
/// (GUIDED_NOGPS) that an onboard computer meets, with COMMAND_ACKs and HEARTBEATs. Not a
/// flight stack: the simulator's own autopilot model (sim::World) flies the setpoint this
/// returns. Pure: frames in, messages out, the time given by the caller.
namespace fnmpc::autopilot {

/// The emulated autopilot's parameters (named after the real ones they play).
struct EmulatedAutopilotSettings {
  AutopilotKind autopilot = AutopilotKind::kPx4;
  int system_id = 1;
  int component_id = 1;
  double heartbeat_period = 1.0;  ///< [s]
  /// No setpoint this long in OFFBOARD / GUIDED_NOGPS: failsafe, the autopilot lands [s].
  /// PX4: COM_OF_LOSS_T (default 1 s). ArduPilot: GUID_TIMEOUT (default 3 s).
  double setpoint_timeout = 1.0;
  /// PX4 only: OFFBOARD is accepted after a setpoint stream of more than `min_setpoint_rate`
  /// for this long [s] (PX4 user guide, "Offboard Mode").
  double offboard_warmup = 1.0;
  double min_setpoint_rate = 2.0;  ///< [Hz]
  /// ArduPilot only: GUID_OPTIONS. Bit 3 (8): SET_ATTITUDE_TARGET's thrust is thrust, not a
  /// climb rate. The emulator plays only that meaning: without the bit it refuses to arm.
  int guid_options = 8;
  /// The land detector that decides whether a disarm by command is accepted.
  LandDetectorSettings land_detector;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("heartbeat_period", &heartbeat_period, Positive().AtMost(5.0, "s"), "[s]");
    a->Visit("setpoint_timeout", &setpoint_timeout, Positive().AtMost(30.0, "s"),
             "[s] setpoint loss -> land (PX4 COM_OF_LOSS_T, ArduPilot GUID_TIMEOUT)");
    a->Visit("offboard_warmup", &offboard_warmup, NonNegative().AtMost(10.0, "s"),
             "[s] PX4: setpoint stream needed before OFFBOARD");
    a->Visit("min_setpoint_rate", &min_setpoint_rate, Positive().AtMost(1000.0, "Hz"),
             "[Hz] PX4: the stream's minimum rate");
    a->Visit("guid_options", &guid_options, IntIn(0, 65535), "ArduPilot GUID_OPTIONS");
    a->Nested("land_detector", &land_detector);
  }
};

/// What the emulated autopilot did last (for the endpoint's log).
enum class EmulatorEvent : int {
  kNone = 0,
  kModeChanged = 1,     ///< a mode request accepted
  kModeRejected = 2,    ///< a mode request refused (no setpoint stream)
  kArmed = 3,           ///< armed by command
  kArmRejected = 4,     ///< arming refused (wrong mode, no stream, GUID_OPTIONS)
  kDisarmed = 5,        ///< disarmed by command or by Disarm()
  kSetpointLost = 6,    ///< setpoint timeout: failsafe, landing
  kUnknownCommand = 7,  ///< a COMMAND_LONG it does not play: MAV_RESULT_UNSUPPORTED
  kDisarmRefused = 8,   ///< disarm by command refused: the land detector has not confirmed
  kLandDisarmed = 9,    ///< PX4: disarmed by itself COM_DISARM_LAND after landed
  kPilotMode = 10,      ///< the pilot selected a mode (SelectMode)
};
std::string_view ToString(EmulatorEvent event);

class EmulatedAutopilot {
 public:
  explicit EmulatedAutopilot(const EmulatedAutopilotSettings& settings);

  /// A frame from the link: SET_ATTITUDE_TARGET to this system (stored), COMMAND_LONG
  /// (answered with COMMAND_ACK into `out`). Others are ignored.
  void OnFrame(const mavlink::Frame& frame, double now, Outbox* out);
  /// HEARTBEAT when due, the setpoint-loss failsafe and the land detector, fed with what the
  /// vehicle does (`motion`: its speeds and rates; the thrust is the setpoint flown).
  void Step(double now, Outbox* out, const LandDetectorInput& motion = {});
  /// The pilot (or a ground station) selects `mode` by its own means (RC switch): no ACK.
  void SelectMode(FlightMode mode, double now);
  /// The setpoint it flies at `now`: the last one received while armed in OFFBOARD /
  /// GUIDED_NOGPS and not lost; invalid otherwise (disarmed, other mode, failsafe).
  [[nodiscard]] AttitudeSetpoint Flying(double now) const;
  /// The land detector stopped the motors (sim::World): disarmed.
  void Disarm(double now);

  [[nodiscard]] bool armed() const { return armed_; }
  [[nodiscard]] FlightMode mode() const { return mode_; }
  [[nodiscard]] bool failsafe() const { return failsafe_; }
  [[nodiscard]] double failsafe_time() const { return failsafe_time_; }
  /// The last event and when it happened; Take clears it.
  EmulatorEvent TakeEvent(double* time);
  [[nodiscard]] const EmulatedAutopilotSettings& settings() const { return settings_; }

 private:
  void Ack(const mavlink::Frame& frame, std::uint16_t command, std::uint8_t result, Outbox* out);
  void Note(EmulatorEvent e, double now);
  void Disarmed(double now, EmulatorEvent why);
  [[nodiscard]] bool StreamAlive(double now) const;

  EmulatedAutopilotSettings settings_;
  bool armed_ = false;
  bool failsafe_ = false;
  double failsafe_time_ = kNaN;
  FlightMode mode_ = FlightMode::kOther;
  AttitudeSetpoint setpoint_;
  double setpoint_time_ = kNaN;  // last SET_ATTITUDE_TARGET [s]
  double stream_start_ = kNaN;   // start of the current setpoint stream [s]
  double last_heartbeat_ = kNaN;
  LandDetector land_detector_;
  EmulatorEvent event_ = EmulatorEvent::kNone;
  double event_time_ = kNaN;
};

}  // namespace fnmpc::autopilot

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstdint>

#include "fnmpc/autopilot/land_detector.hpp"
#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/autopilot/outbox.hpp"
#include "fnmpc/autopilot/setpoint.hpp"
#include "fnmpc/core/sensors.hpp"
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
  /// Rates of the autopilot's own streams the estimators use [Hz] until an onboard computer
  /// changes them with MAV_CMD_SET_MESSAGE_INTERVAL; -1: the autopilot's default
  /// (PX4's onboard mode, src/modules/mavlink/mavlink_main.cpp: HIGHRES_IMU 50, ATTITUDE 100,
  /// SYS_STATUS 5; ArduPilot: HIGHRES_IMU not streamed, ATTITUDE at SR2_EXTRA1 and SYS_STATUS
  /// at SR2_EXT_STAT as docs/autopilot.md sets them, 50 and 2). 0: not streamed. The
  /// simulator's sensor rate caps every stream.
  double highres_imu_rate = -1.0;
  double attitude_rate = -1.0;
  double sys_status_rate = -1.0;

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
    a->Visit("highres_imu_rate", &highres_imu_rate, Finite().AtMost(1000.0, "Hz"),
             "[Hz] HIGHRES_IMU stream (-1: the autopilot's default, 0: none)");
    a->Visit("attitude_rate", &attitude_rate, Finite().AtMost(1000.0, "Hz"),
             "[Hz] ATTITUDE stream (-1: the autopilot's default, 0: none)");
    a->Visit("sys_status_rate", &sys_status_rate, Finite().AtMost(1000.0, "Hz"),
             "[Hz] SYS_STATUS stream (-1: the autopilot's default, 0: none)");
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
  kStreamRate = 11,     ///< a stream's rate set by MAV_CMD_SET_MESSAGE_INTERVAL
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
  /// Whether a measurement of `kind` stamped `stamp` goes out: the autopilot's own streams
  /// (kImu as HIGHRES_IMU, kCompass as ATTITUDE, kBattery as SYS_STATUS) at their current
  /// rates, decimated from the simulator's samples; every other kind (motion capture, flow,
  /// relative: a bridge's, not the autopilot's) always.
  bool Streams(SensorKind kind, double stamp);
  /// The current rate of the stream carrying `kind` [Hz] (0: not streamed; kInf: not one of
  /// the autopilot's streams).
  [[nodiscard]] double StreamRate(SensorKind kind) const;
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
  // Per SensorKind: the stream's rate [Hz] and the next stamp due.
  std::array<double, kNumSensorKinds> stream_rate_{};
  std::array<double, kNumSensorKinds> default_rate_{};  // the settings' (interval 0 restores)
  std::array<double, kNumSensorKinds> stream_next_{};
  EmulatorEvent event_ = EmulatorEvent::kNone;
  double event_time_ = kNaN;
};

}  // namespace fnmpc::autopilot

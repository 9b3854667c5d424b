// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fnmpc/autopilot/modes.hpp"
#include "fnmpc/autopilot/outbox.hpp"
#include "fnmpc/autopilot/setpoint.hpp"
#include "fnmpc/core/serialize.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/mavlink/parser.hpp"

/// The onboard computer's side of the link to one flight controller: the PX4 offboard and
/// ArduPilot GUIDED_NOGPS handshakes (setpoint stream, mode request, arming, with
/// COMMAND_ACK handling and retries), the setpoint stream while the autopilot flies our
/// setpoints, and the watchdogs that hand control back. Pure: frames in, messages out
/// (Outbox), the time given by the caller. docs/autopilot.md has the state diagram.
namespace fnmpc::autopilot {

/// Settings of a session (the `link` keys of docs/autopilot.md).
struct SessionSettings {
  AutopilotKind autopilot = AutopilotKind::kPx4;
  int target_system = 1;          ///< the flight controller's system id
  int target_component = 1;       ///< its component id (MAV_COMP_ID_AUTOPILOT1)
  int system_id = 1;              ///< ours: the vehicle's system id (MAVLink: one per vehicle)
  int component_id = 191;         ///< ours: MAV_COMP_ID_ONBOARD_COMPUTER
  double heartbeat_period = 1.0;  ///< our HEARTBEAT [s] (MAVLink: 1 Hz)
  /// Setpoints streamed before the mode request [s]. PX4 accepts OFFBOARD only after more
  /// than 1 s of setpoints at more than 2 Hz (user guide, "Offboard Mode"); 1.5 s makes the
  /// first request succeed.
  double warmup = 1.5;
  double command_timeout = 0.5;  ///< wait for a COMMAND_ACK before resending [s]
  int command_attempts = 5;      ///< sends of one command before the session fails
  /// No frame from the flight controller for this long: the link is lost [s].
  double state_timeout = 0.2;
  /// No HEARTBEAT from it for this long: the link is lost [s]. Autopilots send HEARTBEAT at
  /// 1 Hz, so this must be longer than 1 s; the state stream (tens of Hz) is what detects a
  /// loss within `state_timeout`.
  double heartbeat_timeout = 1.5;
  bool arm = true;  ///< arm by COMMAND_LONG; false: wait for the pilot to arm
  /// After landing: DISARM is resent every `command_timeout` while the autopilot refuses it
  /// (its land detector has not confirmed yet), idle thrust and level attitude streamed
  /// meanwhile, for at most this long [s]; then the session hands back (the autopilot's
  /// offboard-loss failsafe lands and disarms). PX4 confirms about 0.9 s after idle, ArduPilot
  /// 1 s (docs/autopilot.md "Landing and disarm").
  double disarm_timeout = 10.0;
  /// From the first frame of the flight controller to the session active: the warm-up, the
  /// first HEARTBEAT, the mode request and arming with their ACKs and the HEARTBEATs that
  /// confirm them (1 Hz), with resends [s]. `fly` needs the take-off at least this late.
  double handshake_time = 5.0;
  /// HIGHRES_IMU rate asked of the autopilot with MAV_CMD_SET_MESSAGE_INTERVAL during the
  /// warm-up [Hz] (the estimator's IMU rate); 0: no request (the autopilot's own rate: PX4's
  /// onboard mode 50 Hz, ArduPilot none). A refusal is logged, not fatal: the estimators run
  /// on what arrives.
  double imu_rate = 0.0;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("target_system", &target_system, IntIn(1, 255), "flight controller's system id");
    a->Visit("target_component", &target_component, IntIn(1, 255),
             "flight controller's component id (1: MAV_COMP_ID_AUTOPILOT1)");
    a->Visit("system_id", &system_id, IntIn(1, 255), "our system id");
    a->Visit("component_id", &component_id, IntIn(1, 255),
             "our component id (191: onboard computer)");
    a->Visit("heartbeat_period", &heartbeat_period, Positive().AtMost(5.0, "s"),
             "[s] our HEARTBEAT period");
    a->Visit("warmup", &warmup, NonNegative().AtMost(10.0, "s"),
             "[s] setpoints streamed before the mode request (PX4: > 2 Hz before OFFBOARD)");
    a->Visit("command_timeout", &command_timeout, Positive().AtMost(10.0, "s"),
             "[s] wait for COMMAND_ACK before resending");
    a->Visit("command_attempts", &command_attempts, IntIn(1, 20),
             "sends of one command before giving up");
    a->Visit("state_timeout", &state_timeout, Positive().AtMost(5.0, "s"),
             "[s] no frame from the flight controller this long: link lost");
    a->Visit("heartbeat_timeout", &heartbeat_timeout, Positive().AtLeast(1.0, "s"),
             "[s] no HEARTBEAT this long: link lost (autopilots send it at 1 Hz)");
    a->Visit("arm", &arm, AnyValue(), "arm by command; false: wait for the pilot to arm");
    a->Visit("disarm_timeout", &disarm_timeout, Positive().AtMost(120.0, "s"),
             "[s] after landing: keep asking to disarm (idle, level) this long");
    a->Visit("imu_rate", &imu_rate, NonNegative().AtMost(1000.0, "Hz"),
             "[Hz] HIGHRES_IMU rate requested during the warm-up (0: no request)");
    a->Visit("handshake_time", &handshake_time, Positive().AtMost(60.0, "s"),
             "[s] allowance from the first autopilot frame to active (take-off no earlier)");
  }
  /// Throws std::invalid_argument naming the field of a value Serialize's limits reject.
  void Validate() const;
};

enum class SessionState : int {
  kWaitingForAutopilot = 0,  ///< no HEARTBEAT from the flight controller yet
  kWarmingUp = 1,            ///< streaming setpoints before the mode request
  kRequestingMode = 2,       ///< DO_SET_MODE (OFFBOARD / GUIDED_NOGPS) sent, waiting
  kArming = 3,               ///< ARM sent (or waiting for the pilot), waiting
  kActive = 4,               ///< the autopilot flies our setpoints
  kDisarming = 5,            ///< landed: idle thrust streamed, DISARM sent until confirmed
  kDisarmed = 6,             ///< done: landed and disarmed
  kHandedBack = 7,           ///< control handed back to the autopilot (watchdog, pilot)
  kFailed = 8,               ///< the handshake failed (rejected, no answer)
};
std::string_view ToString(SessionState state);

/// Why the session changed state (kNone for the handshake's own steps).
enum class SessionReason : int {
  kNone = 0,
  kStateStreamLost = 1,      ///< no frame for state_timeout
  kHeartbeatLost = 2,        ///< no HEARTBEAT for heartbeat_timeout
  kModeChanged = 3,          ///< the autopilot left OFFBOARD / GUIDED_NOGPS (pilot, failsafe)
  kDisarmedByAutopilot = 4,  ///< disarmed while active
  kCommandRejected = 5,      ///< a command was denied, unsupported or failed
  kCommandTimedOut = 6,      ///< no COMMAND_ACK after command_attempts sends
  kWrongAutopilot = 7,       ///< the HEARTBEAT names another autopilot than configured
  kRequested = 8,            ///< HandBack() by the caller
  kDisarmRefused = 9,        ///< landed, but the autopilot refused to disarm for disarm_timeout
  kStreamRequest = 10,       ///< the stream request was answered (event only; result inside)
};
std::string_view ToString(SessionReason reason);

/// One state change, for the log.
struct SessionEvent {
  double time = kNaN;
  SessionState state = SessionState::kWaitingForAutopilot;  ///< the new state
  SessionReason reason = SessionReason::kNone;
  std::uint16_t command = 0;  ///< the MAV_CMD concerned (0: none)
  int result = -1;            ///< its MAV_RESULT (-1: none)
};

class AutopilotSession {
 public:
  /// Throws std::invalid_argument on invalid settings.
  explicit AutopilotSession(const SessionSettings& settings);

  /// A frame from the link. Only the flight controller's (target system and component)
  /// count: any of its frames refreshes the state watchdog, its HEARTBEAT gives the mode and
  /// armed state, its COMMAND_ACK addressed to us (our system and component, or 0) answers
  /// our pending command. Other components of the vehicle (a motion-capture bridge) feed
  /// nothing here.
  void OnFrame(const mavlink::Frame& frame, double now);
  /// One control step at `now` [s]: our HEARTBEAT when due, the watchdogs, the next step of
  /// the handshake, and `setpoint` (stamped `time_boot_ms`) while the session streams
  /// (warm-up to active). An invalid setpoint is never sent (counted: skipped_setpoints()).
  void Step(double now, const AttitudeSetpoint& setpoint, std::uint32_t time_boot_ms, Outbox* out);
  /// After landing: disarm (active only). The next Steps stream idle thrust at a level
  /// attitude and send DISARM until a HEARTBEAT shows the vehicle disarmed (refusals while
  /// the autopilot's land detector has not confirmed are retried for disarm_timeout).
  void RequestDisarm(double now);
  /// Stops streaming now; the autopilot's own failsafe takes over (operator, app shutdown).
  void HandBack(double now, SessionReason reason = SessionReason::kRequested);

  [[nodiscard]] SessionState state() const { return state_; }
  [[nodiscard]] SessionReason reason() const { return reason_; }
  /// The autopilot flies our setpoints.
  [[nodiscard]] bool active() const { return state_ == SessionState::kActive; }
  /// Still streaming setpoints (warm-up to disarming).
  [[nodiscard]] bool streaming() const;
  /// Ended: disarmed, handed back or failed.
  [[nodiscard]] bool finished() const;
  [[nodiscard]] bool armed() const { return armed_; }
  [[nodiscard]] FlightMode mode() const { return mode_; }
  [[nodiscard]] bool heard_autopilot() const { return heard_; }
  [[nodiscard]] long skipped_setpoints() const { return skipped_; }
  [[nodiscard]] long setpoints_sent() const { return sent_; }
  [[nodiscard]] const SessionSettings& settings() const { return settings_; }
  /// The oldest state change not yet popped; false when none (16 are kept, the oldest lost
  /// first).
  bool PopEvent(SessionEvent* event);

 private:
  struct Pending {
    bool active = false;
    mavlink::CommandLong command;
    double sent = kNaN;
    int sends = 0;
  };
  void Enter(double now, SessionState state, SessionReason reason, std::uint16_t command = 0,
             int result = -1);
  // Appends an event without a state change (the current state).
  void LogEvent(double now, SessionReason reason, std::uint16_t command, int result);
  void SendCommand(double now, std::uint16_t command, float p1, float p2, float p3, Outbox* out);
  void OnAck(const mavlink::CommandAck& ack, double now);
  void Watchdogs(double now);
  void Handshake(double now, Outbox* out);
  [[nodiscard]] double ResendAfter() const;

  SessionSettings settings_;
  SessionState state_ = SessionState::kWaitingForAutopilot;
  SessionReason reason_ = SessionReason::kNone;
  bool heard_ = false;
  bool armed_ = false;
  bool seen_active_mode_ = false;  // a HEARTBEAT showed OFFBOARD since the mode request
  bool seen_armed_ = false;        // a HEARTBEAT showed armed since the mode request
  bool seen_disarmed_ = false;     // a HEARTBEAT showed disarmed while disarming
  // The autopilot accepted our mode request / arming: the next HEARTBEAT must show it (else
  // someone else changed it: the pilot, a failsafe).
  bool mode_accepted_ = false, arm_accepted_ = false;
  bool contradicted_ = false;  // a HEARTBEAT after an accepted command did not show it
  double disarm_start_ = kNaN;
  double last_yaw_ = kNaN;          // of the last setpoint sent: held while disarming
  bool stream_requested_ = false;   // the IMU stream request was answered or given up
  SessionEvent last_event_of_ack_;  // the accepted ACK, logged with the confirmed state
  bool has_ack_event_ = false;
  FlightMode mode_ = FlightMode::kOther;
  double last_frame_ = kNaN, last_heartbeat_ = kNaN, last_own_heartbeat_ = kNaN;
  double warmup_start_ = kNaN;
  Pending pending_;
  std::uint8_t last_ack_result_ = 0;
  bool ack_received_ = false;
  long skipped_ = 0, sent_ = 0;
  std::array<SessionEvent, 16> events_{};
  std::size_t event_head_ = 0, event_count_ = 0;
};

}  // namespace fnmpc::autopilot

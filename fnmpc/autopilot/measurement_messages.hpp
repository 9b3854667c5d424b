// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>

#include "fnmpc/core/sensors.hpp"
#include "fnmpc/mavlink/message.hpp"

/// The measurements the estimators use, as MAVLink messages on the link (docs/autopilot.md
/// "Measurements"): both directions, so the simulator's endpoint and the onboard executable
/// agree by construction.
///
///   kImu          HIGHRES_IMU (body FRD)
///   kMocapPose    ODOMETRY, estimator MOCAP: pose in LOCAL_NED, body FRD
///   kOpticalFlow  ODOMETRY, estimator VIO: velocity only, in LOCAL_NED (position NaN)
///   kBattery      SYS_STATUS voltage_battery [mV] (no timestamp: stamped on arrival)
///   kRelative     FNMPC_RELATIVE_OBSERVATION (fnmpc dialect)
///   kCompass      ATTITUDE yaw (roll, pitch, rates NaN when we send it; from a real
///                 autopilot its heading estimate, fused from its magnetometer)
///
/// Vehicles are MAVLink systems: vehicle i has system id i + 1.
namespace fnmpc::autopilot {

inline std::uint8_t SystemIdOf(int vehicle) { return static_cast<std::uint8_t>(vehicle + 1); }
inline int VehicleOf(std::uint8_t system_id) { return static_cast<int>(system_id) - 1; }

/// The message carrying `m` (stamps in seconds -> microseconds); false for kinds the link
/// does not carry or a measurement that does not fit (negative stamp, NaN where the message
/// needs a number, relative target not a system id).
bool ToMessage(const Measurement& m, mavlink::Message* out);

/// The measurement `message` carries for `vehicle`, stamped time_usec * 1e-6 + time_offset
/// [s] (`now` for SYS_STATUS, which has no timestamp); arrival = `now`. False when the
/// message carries none (other messages, ODOMETRY of another estimator, unknown fields).
bool FromMessage(const mavlink::Message& message, int vehicle, double time_offset, double now,
                 Measurement* out);

/// The remote sender's clock mapped onto ours from stamped messages: the offset is the
/// smallest (local - remote) seen, i.e. remote time + offset is the stamp shifted by the
/// smallest transport delay seen. Remote time going back by more than `reset_after` [s]
/// (the autopilot rebooted) starts over.
class ClockOffset {
 public:
  explicit ClockOffset(double reset_after = 1.0) : reset_after_(reset_after) {}
  void Observe(double remote, double local);
  [[nodiscard]] bool known() const { return known_; }
  [[nodiscard]] double offset() const { return offset_; }
  [[nodiscard]] long resets() const { return resets_; }

 private:
  double reset_after_;
  bool known_ = false;
  double offset_ = 0.0;
  double last_remote_ = 0.0;
  long resets_ = 0;
};

}  // namespace fnmpc::autopilot

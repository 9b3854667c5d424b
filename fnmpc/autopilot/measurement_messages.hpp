// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
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

/// The remote sender's clock mapped onto ours, with an offset and a rate: local = offset +
/// rate * remote, fitted to the lower envelope of (remote, local) pairs, i.e. to the stamps
/// shifted by the smallest transport delay. The samples are grouped in buckets of `bucket`
/// seconds of remote time; each bucket keeps its least-delayed sample, the rate is the least-
/// squares slope through the last kBuckets of those (once two are closed: after 1 s), and the
/// offset puts the line under every one of them. An autopilot clock running 0.9-1.1 times
/// the wall clock (a lockstep simulation, a crystal's ppm) is then followed, where an offset
/// alone would make its stamps ever older or newer. Until two buckets are full the rate is 1
/// and the offset the smallest (local - remote) seen. Remote time going back by more than
/// `reset_after` [s] (the autopilot rebooted) starts over; a fitted rate outside [0.5, 2] is
/// not believed (rate 1). No allocation.
class ClockMap {
 public:
  static constexpr int kBuckets = 32;
  explicit ClockMap(double reset_after = 1.0, double bucket = 0.5)
      : reset_after_(reset_after), bucket_(bucket) {}
  void Observe(double remote, double local);
  [[nodiscard]] bool known() const { return count_ > 0; }
  /// The local time of remote time `remote` (known() only).
  [[nodiscard]] double ToLocal(double remote) const {
    return local0_ + rate_ * (remote - remote0_);
  }
  [[nodiscard]] double rate() const { return rate_; }
  [[nodiscard]] long resets() const { return resets_; }

 private:
  struct Sample {
    double remote = 0.0, local = 0.0;
  };
  void Fit();

  double reset_after_, bucket_;
  std::array<Sample, kBuckets + 1> samples_{};  // closed buckets' minima, then the open one
  int count_ = 0;                               // samples_ in use (the open bucket last)
  double bucket_start_ = 0.0;                   // remote time the open bucket began
  double last_remote_ = 0.0;
  double rate_ = 1.0, remote0_ = 0.0, local0_ = 0.0;
  long resets_ = 0;
};

}  // namespace fnmpc::autopilot

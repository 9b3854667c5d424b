// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"

namespace fnmpc::formation {

/// Gains of the take-off / landing controller.
struct TakeoffPidConfig {
  double kp_z = 4.0;          ///< height error to vertical acceleration [1/s^2]
  double kd_z = 3.0;          ///< vertical speed error to acceleration [1/s]
  double ki_z = 1.5;          ///< integral gain [1/s^3]
  double max_integral = 2.0;  ///< bound of the integral acceleration term [m/s^2]
  double kv_xy = 1.5;         ///< horizontal velocity damping [1/s] (no absolute position)
  double max_tilt = 0.2;      ///< bound on the roll and pitch references [rad]
  double max_thrust = 25.0;   ///< [N]

  /// Throws std::invalid_argument naming the field on a negative or non-finite gain.
  void Validate() const;
};

/// Output of TakeoffPid::Update.
struct PidCommand {
  double thrust = kNaN;  ///< collective thrust [N]
  double roll = kNaN;    ///< [rad]
  double pitch = kNaN;   ///< [rad]
};

/// The separate take-off and landing controller of the reference work: PID on the height
/// (thrust), horizontal velocity damping through roll and pitch (the follower has no
/// absolute horizontal position). Pure function of its inputs plus the integral state.
class TakeoffPid {
 public:
  TakeoffPid(const TakeoffPidConfig& config, double mass);
  /// Sets the integral so that zero errors reproduce `thrust` [N] in level flight
  /// (bumpless hand-over from another controller).
  void Reset(double thrust);
  /// One step of length dt [s]: height reference z_ref [m] and its rate vz_ref [m/s],
  /// measured height z [m], velocity [m/s] (world), Euler angles [rad], yaw reference.
  /// Non-finite inputs give a non-finite command (the caller guards it).
  PidCommand Update(double dt, double z_ref, double vz_ref, double z, const Vec3& velocity,
                    const Vec3& euler);

 private:
  TakeoffPidConfig config_;
  double mass_;
  double integral_ = 0.0;  // [m/s^2]
};

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"

namespace fnmpc::formation {

/// Gains of the take-off / landing controller.
///
/// Vertical loop: PID on the height with a triple pole at -1.5 1/s (s^3 + kd s^2 + kp s + ki
/// = (s + 1.5)^3), the horizontal loop's frequency; the thrust responds within the motor time
/// constant (0.02 s), far faster. The former gains (4, 3, 1.5) had a slow real pole at
/// -0.58 1/s: after a gust (another vehicle's wake) the integral took about 10 s to unwind and
/// the take-off could not complete. The integral is bounded only by the actuator (zero
/// thrust to `max_thrust` in level flight), so any steady push the thrust margin can fly
/// against is compensated (the 2 m/s^2 bound before could not cancel a wake of 40-50 % of the
/// weight, docs/simulator.md).
///
/// Horizontal loop: a PID on the horizontal position error from the vehicle's own estimate,
/// acting through small roll/pitch references (a = kp_xy e - kv_xy v + integral, tilt = a/g).
/// Rationale of the defaults: the autopilot's attitude loop is a first-order lag of about
/// 0.12–0.13 s (vehicle file `attitude.time_constant`, i.e. about 8 rad/s), so the position
/// loop is placed a factor of about 5 below it: natural frequency 1.5 rad/s, critically
/// damped (kp_xy = 1.5^2, kv_xy = 2 * 1.5). The integral absorbs a constant tilt such as a
/// level-calibration (attitude) bias; with ki_xy = 0.5 the closed loop's poles are
/// -0.5, -0.5, -2 1/s (s^3 + kv s^2 + kp s + ki = (s + 0.5)^2 (s + 2)), so the bias is
/// removed in a few seconds of the take-off. It is bounded at max_integral_xy = 1 m/s^2, the
/// acceleration of a tilt of about 0.1 rad (5.8 deg, three times the largest level-calibration
/// error of small autopilots, docs/simulator.md "Reality"), half the tilt bound, so the P and
/// D terms keep their authority. Without an integral, a bias b leaves a steady offset g b /
/// kp_xy (0.15 m at 2 deg).
struct TakeoffPidConfig {
  double kp_z = 6.75;            ///< height error to vertical acceleration [1/s^2]
  double kd_z = 4.5;             ///< vertical speed error to acceleration [1/s]
  double ki_z = 3.375;           ///< integral gain [1/s^3]
  double kp_xy = 2.25;           ///< horizontal position error to acceleration [1/s^2]
  double kv_xy = 3.0;            ///< horizontal velocity damping [1/s]
  double ki_xy = 0.5;            ///< horizontal integral gain [1/s^3]
  double max_integral_xy = 1.0;  ///< bound of each horizontal integral term [m/s^2]
  double max_tilt = 0.2;         ///< bound on the roll and pitch references [rad]
  double max_thrust = 25.0;      ///< [N]

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
/// (thrust) and, when a horizontal position error is given, PID on the horizontal position
/// through roll and pitch (else horizontal velocity damping only). Pure function of its
/// inputs plus the integral states.
class TakeoffPid {
 public:
  TakeoffPid(const TakeoffPidConfig& config, double mass);
  /// Sets the vertical integral so that zero errors reproduce `thrust` [N] in level flight
  /// (bumpless hand-over from another controller) and clears the horizontal integral.
  void Reset(double thrust);
  /// One step of length dt [s]: height reference z_ref [m] and its rate vz_ref [m/s],
  /// measured height z [m], velocity [m/s] (world), Euler angles [rad], and the horizontal
  /// position error xy_error = reference - position [m] (world x, y). A non-finite xy_error
  /// means "no horizontal position": velocity damping only, the horizontal integral held.
  /// Other non-finite inputs give a non-finite command (the caller guards it).
  PidCommand Update(double dt, double z_ref, double vz_ref, double z, const Vec3& velocity,
                    const Vec3& euler, const Vec<2>& xy_error);

  /// The horizontal integral [m/s^2] (world x, y), for tests and logs.
  [[nodiscard]] const Vec<2>& HorizontalIntegral() const { return integral_xy_; }

 private:
  TakeoffPidConfig config_;
  double mass_;
  double max_integral_ = 0.0;            // [m/s^2], from max_thrust
  double integral_ = 0.0;                // [m/s^2], in [-g, max_integral_]
  Vec<2> integral_xy_ = Vec<2>::Zero();  // [m/s^2]
};

}  // namespace fnmpc::formation

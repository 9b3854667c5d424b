// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/autopilot_model.hpp"

#include <algorithm>
#include <cmath>

#include "fnmpc/core/rotation.hpp"

namespace fnmpc::sim {

double ThrustForThrottle(const model::ThrottlePolynomial& p, double throttle, double voltage,
                         double* guess) {
  if (throttle <= 0.0 || throttle <= p.Throttle(0.0, voltage)) return 0.0;
  double f = *guess;
  if (f > 0.0) {
    for (int it = 0; it < 6; ++it) {
      const double r = p.Throttle(f, voltage) - throttle;
      if (std::abs(r) < 1e-13) {
        *guess = f;
        return f;
      }
      const double d = p.DThrottleDThrust(f, voltage);
      if (!(d > 0.0)) break;
      f -= r / d;
      if (!(f > 0.0)) break;
    }
  }
  f = p.Thrust(throttle, voltage);
  if (!std::isfinite(f)) f = p.Thrust(throttle, voltage, 200.0);
  if (!std::isfinite(f)) f = 0.0;
  *guess = f;
  return f;
}

namespace detail {

namespace {

/// Command-timeout failsafe (CommandTimeoutSettings): engages on a stale command stream
/// of an armed vehicle, then replaces the command by level attitude and a vertical-speed
/// loop to the descent speed; the land detector disarms.
void CommandTimeout(const WorldConfig& config, double t, const Kinematics& kin, Vehicle& v) {
  const CommandTimeoutSettings& c = config.command_timeout;
  AutopilotStatus& st = v.status;
  if (!c.enabled || v.direct || st.motors_killed || st.disarmed_by_failsafe) return;
  if (!st.failsafe) {
    if (!st.armed || !std::isfinite(st.last_command_time) ||
        t - st.last_command_time <= c.timeout + kTimeEps) {
      return;
    }
    st.failsafe = true;
    st.failsafe_time = t;
    v.failsafe_yaw = EulerZyx(QuaternionRotation(kin.quaternion)).z();
    v.land_timer = 0.0;
  }
  const Mat3 r = QuaternionRotation(kin.quaternion);
  const double vz = kin.velocity.z();
  const double accel = c.velocity_gain * (-c.descent_speed - vz);  // about hover [m/s^2]
  const double tilt = std::max(0.5, r(2, 2));                      // cos roll cos pitch
  AttitudeCommand cmd;
  cmd.thrust = std::max(0.0, v.params.mass * (config.gravity + accel) / tilt);
  cmd.yaw = v.failsafe_yaw;
  if (std::abs(vz) < c.land_speed && accel < 0.0) {
    v.land_timer += 1.0 / config.autopilot_rate_hz;
  } else {
    v.land_timer = 0.0;
  }
  if (v.land_timer >= c.land_detect_time - kTimeEps) {
    st.disarmed_by_failsafe = true;
    st.disarm_time = t;
    cmd.thrust = 0.0;
  }
  v.command = cmd;
}

}  // namespace

void AutopilotTick(const WorldConfig& config, double t, const Kinematics& kin, Vehicle& v) {
  const model::VehicleParams& p = v.params;
  const double volt = v.battery.voltage;
  Vec4 f_ss;
  if (v.status.motors_killed) {
    v.throttle.setZero();
    v.rpm_target.setZero();
    return;
  }
  CommandTimeout(config, t, kin, v);
  // Collective thrust [N]: from the throttle command through the polynomial at the
  // present voltage when it is set, else the thrust command.
  double commanded = v.command.thrust;
  if (!std::isnan(v.command.throttle)) {
    const double thr = std::clamp(v.command.throttle, 0.0, 1.0);
    commanded = 4.0 * ThrustForThrottle(p.throttle, thr, volt, &v.collective_guess);
  }
  v.status.armed = v.direct || commanded > 0.0;
  if (!v.direct && !(commanded > 0.0)) {
    // Zero thrust command: the autopilot idles the motors (as a disarmed vehicle).
    v.throttle.setZero();
    f_ss.setZero();
  } else if (v.direct) {
    for (int r = 0; r < 4; ++r) {
      f_ss[r] = ThrustForThrottle(p.throttle, v.throttle[r], volt, &v.thrust_guess[r]);
    }
  } else {
    const bool own = config.sensor_reality.enabled && config.sensor_reality.autopilot_estimate;
    const Mat3 rot_wb = own ? v.attitude_estimate : QuaternionRotation(kin.quaternion);
    const Vec3 eul = EulerZyx(rot_wb);
    const Vec3 w = own ? v.autopilot_gyro : kin.rates;
    const AttitudeCommand& c = v.command;
    const Vec3 k = p.attitude_gain;
    Vec3 e(k.x() * (c.roll + p.bias.roll) - eul.x(), k.y() * (c.pitch + p.bias.pitch) - eul.y(),
           WrapAngle(k.z() * c.yaw - eul.z()));
    const Vec3 torque =
        p.inertia.cwiseProduct(p.attitude_kp.cwiseProduct(e) - p.attitude_kd.cwiseProduct(w));
    const double thrust = std::max(0.0, p.bias.thrust_scale * commanded);
    const Vec4 f_base = v.mix_inv * Vec4(thrust, torque.x(), torque.y(), 0.0);
    const Vec4 f_yaw = v.mix_inv.col(3) * torque.z();
    double fmax = ThrustForThrottle(p.throttle, 1.0, volt, &v.fmax_guess);
    if (!(fmax > 0.0)) fmax = kInf;
    // Roll, pitch and thrust first: shrink the yaw part until every rotor fits.
    double alpha = 1.0;
    for (int r = 0; r < 4; ++r) {
      const double val = f_base[r] + f_yaw[r];
      if (f_yaw[r] < 0.0 && val < 0.0)
        alpha = std::min(alpha, std::max(0.0, -f_base[r] / f_yaw[r]));
      if (f_yaw[r] > 0.0 && val > fmax) {
        alpha = std::min(alpha, std::max(0.0, (fmax - f_base[r]) / f_yaw[r]));
      }
    }
    for (int r = 0; r < 4; ++r) {
      const double f = std::clamp(f_base[r] + alpha * f_yaw[r], 0.0, fmax);
      double thr = f > 0.0 ? p.throttle.Throttle(f, volt) : 0.0;
      if (thr >= 0.0 && thr <= 1.0) {
        f_ss[r] = f;
      } else {
        thr = std::clamp(thr, 0.0, 1.0);
        f_ss[r] = ThrustForThrottle(p.throttle, thr, volt, &v.thrust_guess[r]);
      }
      v.throttle[r] = thr;
    }
  }
  for (int r = 0; r < 4; ++r)
    v.rpm_target[r] = std::sqrt(std::max(0.0, f_ss[r]) / p.thrust_constant);
}

}  // namespace detail

}  // namespace fnmpc::sim

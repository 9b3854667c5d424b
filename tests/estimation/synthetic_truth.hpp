// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Deterministic synthetic truth and sensor generator for the estimator tests: smooth 3D
// trajectories with consistent attitude (thrust direction along the acceleration),
// body rates, specific force, IMU biases as random walks, and every sensor of
// core/sensors.hpp sampled at its own rate with its configured noise and latency.

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/core/sensors.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/estimation/vehicle_ekf.hpp"

namespace fnmpc::estimation::testing {

/// A VehicleEkf configuration that starts in flight and stays there (no take-off/landing
/// detection), for tests of the in-flight filter.
inline VehicleEkfConfig FlyingConfig() {
  VehicleEkfConfig c;
  c.initial_mode = VehicleMode::kFlying;
  c.auto_mode_switch = false;
  return c;
}

/// Truth of one rigid body at one time.
struct TruthSample {
  Vec3 p = Vec3::Zero();                       ///< position {n} [m]
  Vec3 v = Vec3::Zero();                       ///< velocity {n} [m/s]
  Vec3 a = Vec3::Zero();                       ///< acceleration {n} [m/s^2]
  Vec3 euler = Vec3::Zero();                   ///< roll, pitch, yaw [rad]
  Vec3 omega = Vec3::Zero();                   ///< body angular rate [rad/s]
  Vec3 specific_force = Vec3(0, 0, kGravity);  ///< body [m/s^2]
};

/// Smooth trajectory: position/velocity/acceleration analytic; attitude from the
/// acceleration (thrust along body z) and a given yaw; body rates by central differences.
class Trajectory {
 public:
  virtual ~Trajectory() = default;
  virtual void Kinematics(double t, Vec3* p, Vec3* v, Vec3* a) const = 0;
  virtual double Yaw(double t) const = 0;
  /// Tilted attitude from the acceleration (false: level, e.g. a vertical profile).
  virtual bool tilt() const { return true; }

  Vec3 Euler(double t) const {
    Vec3 p, v, a;
    Kinematics(t, &p, &v, &a);
    const double psi = Yaw(t);
    if (!tilt()) return {0.0, 0.0, psi};
    const Vec3 b3 = (a + Vec3(0, 0, kGravity)).normalized();
    const Vec3 c = RotationZ(psi).transpose() * b3;  // = (s_th c_ph, -s_ph, c_th c_ph)
    return {std::asin(-c.y()), std::atan2(c.x(), c.z()), psi};
  }

  TruthSample At(double t) const {
    TruthSample s;
    Kinematics(t, &s.p, &s.v, &s.a);
    s.euler = Euler(t);
    constexpr double kH = 1e-5;
    Vec3 de = (Euler(t + kH) - Euler(t - kH)) / (2 * kH);
    de.z() = WrapAngle(Euler(t + kH).z() - Euler(t - kH).z()) / (2 * kH);
    const double ph = s.euler.x(), th = s.euler.y();
    Mat3 E;  // omega = E * euler_dot
    E << 1, 0, -std::sin(th), 0, std::cos(ph), std::sin(ph) * std::cos(th), 0, -std::sin(ph),
        std::cos(ph) * std::cos(th);
    s.omega = E * de;
    s.specific_force = RotationZyx(ph, th, s.euler.z()).transpose() * (s.a + Vec3(0, 0, kGravity));
    return s;
  }
};

/// 3D Lissajous figure around `center` with slowly varying yaw.
class LissajousTrajectory : public Trajectory {
 public:
  Vec3 center{0.0, 0.0, 1.5};
  Vec3 amplitude{1.5, 1.0, 0.3};  ///< [m]
  Vec3 omega{0.5, 0.7, 0.9};      ///< [rad/s]
  Vec3 phase{0.3, 0.0, 1.0};      ///< [rad]
  double yaw0 = 0.2, yaw_amplitude = 0.6, yaw_omega = 0.3;

  void Kinematics(double t, Vec3* p, Vec3* v, Vec3* a) const override {
    for (int i = 0; i < 3; ++i) {
      const double arg = omega(i) * t + phase(i);
      (*p)(i) = center(i) + amplitude(i) * std::sin(arg);
      (*v)(i) = amplitude(i) * omega(i) * std::cos(arg);
      (*a)(i) = -amplitude(i) * omega(i) * omega(i) * std::sin(arg);
    }
  }
  double Yaw(double t) const override {
    return WrapAngle(yaw0 + yaw_amplitude * std::sin(yaw_omega * t));
  }
};

/// Vertical flight from the ground: acceleration made of sin^2 bumps A sin^2(pi u),
/// u = (t - start) / duration, each changing the speed by A duration / 2. Level attitude,
/// so the IMU reads (0, 0, a_z + g): at rest on the ground it reads the ground reaction g.
class VerticalProfile : public Trajectory {
 public:
  struct Bump {
    double start, duration, accel;
  };
  std::vector<Bump> bumps;
  Vec3 origin{0.3, -0.2, 0.0};
  double yaw = 0.4;
  bool tilt() const override { return false; }
  double Yaw(double /*t*/) const override { return yaw; }

  void Kinematics(double t, Vec3* p, Vec3* v, Vec3* a) const override {
    double z = 0.0, vz = 0.0, az = 0.0;
    for (const Bump& b : bumps) {
      if (t <= b.start) continue;
      const double T = b.duration, A = b.accel;
      if (t < b.start + T) {
        const double u = (t - b.start) / T;
        az += A * std::sin(M_PI * u) * std::sin(M_PI * u);
        vz += A * T * (u / 2 - std::sin(2 * M_PI * u) / (4 * M_PI));
        z += A * T * T * (u * u / 4 + (std::cos(2 * M_PI * u) - 1) / (8 * M_PI * M_PI));
      } else {
        vz += A * T / 2;
        z += A * T * T / 4 + A * T / 2 * (t - b.start - T);
      }
    }
    *p = origin + Vec3(0, 0, z);
    *v = Vec3(0, 0, vz);
    *a = Vec3(0, 0, az);
  }
};

/// Options of the sensor generator.
struct SensorStreamOptions {
  double t0 = 0.0;   ///< first sample [s]
  double t1 = 10.0;  ///< last sample [s]
  int vehicle = 0;   ///< Measurement::vehicle
  bool imu = true, mocap = true, flow = true, compass = true;
  double accel_bias_noise = 1e-3;   ///< truth bias random walk [m/s^2/sqrt(s)]
  double gyro_bias_noise = 1e-4;    ///< [rad/s/sqrt(s)]
  Vec3 accel_bias0 = Vec3::Zero();  ///< initial biases (drawn by the caller)
  Vec3 gyro_bias0 = Vec3::Zero();
  double arrival_jitter = 0.0;  ///< extra uniform [0, jitter] delivery delay [s]
};

/// One generated stream, sorted by stamp, with the truth biases at each IMU sample.
struct SensorStream {
  std::vector<Measurement> measurements;
  std::vector<double> imu_stamps;
  std::vector<Vec3> accel_bias;  ///< truth bias at imu_stamps[k] (held until the next)
  std::vector<Vec3> gyro_bias;

  /// Truth biases at time t (piecewise constant between IMU samples).
  void BiasAt(double t, Vec3* ba, Vec3* bg) const {
    auto it = std::upper_bound(imu_stamps.begin(), imu_stamps.end(), t);
    const std::size_t k =
        it == imu_stamps.begin() ? 0 : static_cast<std::size_t>(it - imu_stamps.begin() - 1);
    *ba = accel_bias[k];
    *bg = gyro_bias[k];
  }
  /// Measurements sorted by arrival time (ties by stamp).
  std::vector<Measurement> ByArrival() const {
    std::vector<Measurement> out = measurements;
    std::stable_sort(out.begin(), out.end(), [](const Measurement& a, const Measurement& b) {
      return a.arrival < b.arrival;
    });
    return out;
  }
};

inline Vec3 Gaussian3(std::mt19937* rng, const Vec3& std) {
  std::normal_distribution<double> n(0.0, 1.0);
  return {std.x() * n(*rng), std.y() * n(*rng), std.z() * n(*rng)};
}

/// Samples every enabled sensor of `sensors` on its own grid (offset by a fraction of a
/// period so that stamps rarely coincide) with white noise of the configured std.
inline SensorStream GenerateVehicleStream(const Trajectory& traj, const SensorsConfig& sensors,
                                          const SensorStreamOptions& opt, std::mt19937* rng) {
  SensorStream s;
  std::uniform_real_distribution<double> jitter(0.0, opt.arrival_jitter);
  const auto push = [&](Measurement m, const SensorSpec& spec) {
    m.vehicle = opt.vehicle;
    m.arrival = m.stamp + spec.latency_s + (opt.arrival_jitter > 0 ? jitter(*rng) : 0.0);
    s.measurements.push_back(m);
  };
  if (opt.imu) {
    const double dt = 1.0 / sensors.imu.rate_hz;
    Vec3 ba = opt.accel_bias0, bg = opt.gyro_bias0;
    for (int k = 0; opt.t0 + k * dt <= opt.t1; ++k) {
      const double t = opt.t0 + k * dt;
      const TruthSample x = traj.At(t);
      Measurement m;
      m.kind = SensorKind::kImu;
      m.stamp = t;
      m.accel = x.specific_force + ba + Gaussian3(rng, sensors.imu.noise);
      m.gyro = x.omega + bg + Gaussian3(rng, sensors.imu.noise2);
      s.imu_stamps.push_back(t);
      s.accel_bias.push_back(ba);
      s.gyro_bias.push_back(bg);
      push(m, sensors.imu);
      ba += Gaussian3(rng, Vec3::Constant(opt.accel_bias_noise * std::sqrt(dt)));
      bg += Gaussian3(rng, Vec3::Constant(opt.gyro_bias_noise * std::sqrt(dt)));
    }
  }
  if (opt.mocap) {
    const double dt = 1.0 / sensors.mocap.rate_hz;
    for (int k = 0; opt.t0 + (k + 0.3) * dt <= opt.t1; ++k) {
      const double t = opt.t0 + (k + 0.3) * dt;
      const TruthSample x = traj.At(t);
      Measurement m;
      m.kind = SensorKind::kMocapPose;
      m.stamp = t;
      m.position = x.p + Gaussian3(rng, sensors.mocap.noise);
      m.euler = x.euler + Gaussian3(rng, sensors.mocap.noise2);
      m.euler.z() = WrapAngle(m.euler.z());
      push(m, sensors.mocap);
    }
  }
  if (opt.flow) {
    const double dt = 1.0 / sensors.optical_flow.rate_hz;
    for (int k = 0; opt.t0 + (k + 0.55) * dt <= opt.t1; ++k) {
      const double t = opt.t0 + (k + 0.55) * dt;
      Measurement m;
      m.kind = SensorKind::kOpticalFlow;
      m.stamp = t;
      m.velocity = traj.At(t).v + Gaussian3(rng, sensors.optical_flow.noise);
      push(m, sensors.optical_flow);
    }
  }
  if (opt.compass) {
    const double dt = 1.0 / sensors.compass.rate_hz;
    std::normal_distribution<double> n(0.0, sensors.compass.noise.x());
    for (int k = 0; opt.t0 + (k + 0.7) * dt <= opt.t1; ++k) {
      const double t = opt.t0 + (k + 0.7) * dt;
      Measurement m;
      m.kind = SensorKind::kCompass;
      m.stamp = t;
      m.yaw = WrapAngle(traj.At(t).euler.z() + n(*rng));
      push(m, sensors.compass);
    }
  }
  std::stable_sort(s.measurements.begin(), s.measurements.end(),
                   [](const Measurement& a, const Measurement& b) { return a.stamp < b.stamp; });
  return s;
}

/// Relative observation of `target` at p_target with yaw psi_target by an observer at
/// p_obs with attitude euler_obs, without noise (core/sensors.hpp geometry).
inline RelativeObservation TrueRelative(const Vec3& p_obs, const Vec3& euler_obs,
                                        const Vec3& p_target, double psi_target, int target) {
  const Vec3 d =
      RotationZyx(euler_obs.x(), euler_obs.y(), euler_obs.z()).transpose() * (p_target - p_obs);
  RelativeObservation o;
  o.target = target;
  o.range = d.norm();
  o.bearing = std::atan2(d.y(), d.x());
  o.elevation = std::asin(d.z() / o.range);
  o.relative_yaw = WrapAngle(psi_target - euler_obs.z());
  return o;
}

/// Neighbour moving with white-noise acceleration and yaw acceleration (the NeighbourEkf
/// process model), integrated exactly on a fine grid.
struct NeighbourTruth {
  std::vector<double> t;
  std::vector<Vec3> p, v;
  std::vector<double> psi, wz;

  /// Index of the grid sample at time tq (the grid must contain it to 1e-9).
  std::size_t Index(double tq) const {
    const double dt = t[1] - t[0];
    return static_cast<std::size_t>(std::lround((tq - t[0]) / dt));
  }
};

/// Simulates the neighbour on the grid t0 + k dt, k = 0..n: exact discretisation of the
/// white-noise acceleration model with densities q_acc [(m/s^2)^2/Hz] and q_yaw.
inline NeighbourTruth SimulateNeighbour(double t0, double dt, int n, const Vec3& p0, const Vec3& v0,
                                        double psi0, double wz0, double q_acc, double q_yaw,
                                        std::mt19937* rng) {
  NeighbourTruth tr;
  std::normal_distribution<double> nd(0.0, 1.0);
  Vec3 p = p0, v = v0;
  double psi = psi0, wz = wz0;
  // Cholesky factor of [[dt^3/3, dt^2/2], [dt^2/2, dt]].
  const double l11 = std::sqrt(dt * dt * dt / 3.0);
  const double l21 = (dt * dt / 2.0) / l11;
  const double l22 = std::sqrt(dt - l21 * l21);
  for (int k = 0; k <= n; ++k) {
    tr.t.push_back(t0 + k * dt);
    tr.p.push_back(p);
    tr.v.push_back(v);
    tr.psi.push_back(psi);
    tr.wz.push_back(wz);
    for (int i = 0; i < 3; ++i) {
      const double a = nd(*rng), b = nd(*rng);
      p(i) += v(i) * dt + std::sqrt(q_acc) * l11 * a;
      v(i) += std::sqrt(q_acc) * (l21 * a + l22 * b);
    }
    const double a = nd(*rng), b = nd(*rng);
    psi = WrapAngle(psi + wz * dt + std::sqrt(q_yaw) * l11 * a);
    wz += std::sqrt(q_yaw) * (l21 * a + l22 * b);
  }
  return tr;
}

/// Two-sided 95 % bounds of the average of n_samples chi-square(dof) variables
/// (Wilson-Hilferty quantiles of chi-square(n_samples * dof), divided by n_samples).
inline void AverageNeesBounds(int n_samples, int dof, double* lo, double* hi) {
  const double k = static_cast<double>(n_samples) * dof;
  const double c = 2.0 / (9.0 * k);
  const double z = 1.959963984540054;
  *lo = k * std::pow(1.0 - c - z * std::sqrt(c), 3) / n_samples;
  *hi = k * std::pow(1.0 - c + z * std::sqrt(c), 3) / n_samples;
}

}  // namespace fnmpc::estimation::testing

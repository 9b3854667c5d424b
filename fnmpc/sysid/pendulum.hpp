// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <vector>

namespace fnmpc::sysid {

/// Damped free oscillation fitted to a pendulum swing:
/// angle(t) = A exp(-lambda (t - t0)) cos(omega_d (t - t0) + phase) + offset.
struct PendulumFit {
  double natural_period = 0.0;  ///< 2 pi / sqrt(omega_d^2 + lambda^2): period without damping [s]
  double damped_period = 0.0;   ///< 2 pi / omega_d [s]
  double decay_rate = 0.0;      ///< lambda [1/s]
  double amplitude = 0.0;       ///< A at t0 [rad]
  double phase = 0.0;           ///< [rad]
  double offset = 0.0;          ///< [rad]
  double t0 = 0.0;              ///< first sample time [s]
  double rms = 0.0;             ///< RMS residual [rad]
  double noise_sigma = 0.0;     ///< robust noise estimate of the signal [rad]
  double natural_period_std_error = 0.0;  ///< standard error of natural_period [s]
  int samples = 0;

  /// The fitted curve at time t [s].
  [[nodiscard]] double Evaluate(double t) const;
};

/// Period of a noisy, slightly damped swing: a periodogram over frequencies from 2 cycles
/// per record to a quarter of the mean sampling rate gives the start, then Ceres fits the
/// damped sinusoid with a Huber loss (scale 3 noise sigma) on every sample. Times must be
/// increasing. Throws std::invalid_argument with fewer than 20 samples or no oscillation.
PendulumFit FitPendulum(const std::vector<double>& t, const std::vector<double>& angle);

/// Bifilar (double-arm) pendulum: I = m g d^2 T^2 / (16 pi^2 L) [kg m^2], with mass m [kg],
/// wire separation d [m], wire length L [m] and natural period T [s]; g = kGravity.
double BifilarInertia(double mass, double wire_separation, double wire_length, double period);

/// Inverse of BifilarInertia: the natural period [s] of a body of inertia I [kg m^2].
double BifilarPeriod(double mass, double wire_separation, double wire_length, double inertia);

}  // namespace fnmpc::sysid

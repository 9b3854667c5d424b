// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/pendulum.hpp"

#include <ceres/ceres.h>

#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

#include "fnmpc/core/types.hpp"
#include "fnmpc/sysid/trajectory_fit.hpp"

namespace fnmpc::sysid {
namespace {

struct DampedSine {
  const std::vector<double>* t;
  double t0;
  template <class T>
  void operator()(const T* p, std::vector<T>* y) const {
    // p = [A, lambda, omega_d, phase, offset]
    using std::cos;
    using std::exp;
    y->resize(t->size());
    for (std::size_t i = 0; i < t->size(); ++i) {
      const double s = (*t)[i] - t0;
      (*y)[i] = p[0] * exp(-p[1] * s) * cos(p[2] * s + p[3]) + p[4];
    }
  }
};

}  // namespace

double NoiseSigma(const std::vector<double>& y) {
  if (y.size() < 3) return 0.0;
  std::vector<double> d(y.size() - 1);
  for (std::size_t i = 0; i + 1 < y.size(); ++i) d[i] = std::abs(y[i + 1] - y[i]);
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2] / (0.6745 * std::sqrt(2.0));
}

double PendulumFit::Evaluate(double t) const {
  const double omega_d = 2.0 * M_PI / damped_period;
  const double s = t - t0;
  return amplitude * std::exp(-decay_rate * s) * std::cos(omega_d * s + phase) + offset;
}

PendulumFit FitPendulum(const std::vector<double>& t, const std::vector<double>& angle) {
  const std::size_t n = t.size();
  if (angle.size() != n) throw std::invalid_argument("[FitPendulum] t and angle differ in length");
  if (n < 20) {
    throw std::invalid_argument("[FitPendulum] need at least 20 samples, got " + std::to_string(n));
  }
  const double t0 = t.front(), duration = t.back() - t.front();
  if (!(duration > 0.0)) throw std::invalid_argument("[FitPendulum] zero duration");
  double mean = 0.0;
  for (double a : angle) mean += a;
  mean /= static_cast<double>(n);

  // Periodogram start: |sum (a - mean) exp(-i w t)| over a log-spaced frequency grid.
  const double f_lo = 2.0 / duration;
  const double f_hi = 0.25 * static_cast<double>(n - 1) / duration;
  if (!(f_hi > f_lo)) throw std::invalid_argument("[FitPendulum] record too short or too sparse");
  auto power = [&](double f) {
    std::complex<double> s{0.0, 0.0};
    for (std::size_t i = 0; i < n; ++i) {
      s += (angle[i] - mean) * std::polar(1.0, -2.0 * M_PI * f * (t[i] - t0));
    }
    return std::abs(s);
  };
  // Coarse log grid, then a fine grid around the best coarse point.
  const int grid = 400;
  const double ratio = std::pow(f_hi / f_lo, 1.0 / grid);
  double best_f = f_lo, best_p = -1.0;
  for (int g = 0; g <= grid; ++g) {
    const double f = f_lo * std::pow(ratio, g);
    const double p = power(f);
    if (p > best_p) {
      best_p = p;
      best_f = f;
    }
  }
  const double f_c = best_f;
  for (int g = -100; g <= 100; ++g) {
    const double f = f_c * std::pow(ratio, g / 100.0);
    const double p = power(f);
    if (p > best_p) {
      best_p = p;
      best_f = f;
    }
  }
  // Amplitude and phase at that frequency by linear least squares (a cos + b sin).
  const double w0 = 2.0 * M_PI * best_f;
  double cc = 0.0, ss = 0.0, cs = 0.0, cy = 0.0, sy = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double c = std::cos(w0 * (t[i] - t0)), s = std::sin(w0 * (t[i] - t0));
    const double y = angle[i] - mean;
    cc += c * c;
    ss += s * s;
    cs += c * s;
    cy += c * y;
    sy += s * y;
  }
  const double det = cc * ss - cs * cs;
  if (!(std::abs(det) > 0.0)) throw std::invalid_argument("[FitPendulum] no oscillation found");
  const double a = (ss * cy - cs * sy) / det, b = (cc * sy - cs * cy) / det;
  const double amp = std::hypot(a, b);
  if (!(amp > 0.0)) throw std::invalid_argument("[FitPendulum] no oscillation found");

  PendulumFit fit;
  fit.samples = static_cast<int>(n);
  fit.t0 = t0;
  fit.noise_sigma = NoiseSigma(angle);
  const DampedSine sim{&t, t0};
  const std::array<double, 5> p0{amp, 0.0, w0, std::atan2(-b, a), mean};
  const std::array<double, 5> lo{0.0, -1.0 / duration, 0.5 * w0, -4.0 * M_PI, -kInf};
  const std::array<double, 5> hi{10.0 * amp + 1.0, 10.0, 2.0 * w0, 4.0 * M_PI, kInf};
  const auto r = FitTrajectory<5>(sim, angle, p0, lo, hi, 3.0 * fit.noise_sigma);
  if (!r.converged) throw std::invalid_argument("[FitPendulum] the fit did not converge");
  fit.amplitude = r.p[0];
  fit.decay_rate = r.p[1];
  fit.damped_period = 2.0 * M_PI / r.p[2];
  fit.natural_period = 2.0 * M_PI / std::sqrt(r.p[2] * r.p[2] + r.p[1] * r.p[1]);
  fit.phase = r.p[3];
  fit.offset = r.p[4];
  fit.rms = r.rms;
  // T = 2 pi / sqrt(w^2 + l^2): first-order propagation of the standard errors of w, l.
  const double w2 = r.p[2] * r.p[2] + r.p[1] * r.p[1];
  const double dw = 2.0 * M_PI * r.p[2] / std::pow(w2, 1.5);
  const double dl = 2.0 * M_PI * r.p[1] / std::pow(w2, 1.5);
  fit.natural_period_std_error = std::hypot(dw * r.std_error[2], dl * r.std_error[1]);
  return fit;
}

double BifilarInertia(double mass, double d, double length, double period) {
  if (!(mass > 0.0) || !(d > 0.0) || !(length > 0.0) || !(period > 0.0)) {
    throw std::invalid_argument("[BifilarInertia] mass, separation, length and period must be > 0");
  }
  return mass * kGravity * d * d * period * period / (16.0 * M_PI * M_PI * length);
}

double BifilarPeriod(double mass, double d, double length, double inertia) {
  if (!(mass > 0.0) || !(d > 0.0) || !(length > 0.0) || !(inertia > 0.0)) {
    throw std::invalid_argument("[BifilarPeriod] mass, separation, length and inertia must be > 0");
  }
  return 4.0 * M_PI * std::sqrt(inertia * length / (mass * kGravity * d * d));
}

}  // namespace fnmpc::sysid

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/dryden.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fnmpc::sim {

namespace {
constexpr double kFeet = 0.3048;  // [m/ft]
}  // namespace

void DrydenSettings::Validate() const {
  if (!sigma.allFinite() || !(sigma.array() >= 0.0).all()) {
    throw std::invalid_argument("[DrydenSettings] sigma must be finite and >= 0");
  }
  if (!length_scale.allFinite() || !(length_scale.array() > 0.0).all()) {
    throw std::invalid_argument("[DrydenSettings] length_scale must be finite and > 0");
  }
  if (!(airspeed > 0.0) || !std::isfinite(airspeed)) {
    throw std::invalid_argument("[DrydenSettings] airspeed must be > 0, got " +
                                std::to_string(airspeed));
  }
}

DrydenSettings LowAltitudeDryden(double w20, double height, double airspeed) {
  if (!(w20 >= 0.0) || !std::isfinite(w20)) {
    throw std::invalid_argument("[LowAltitudeDryden] w20 must be >= 0, got " + std::to_string(w20));
  }
  if (!(height >= 10.0 * kFeet - 1e-9 && height <= 1000.0 * kFeet)) {
    throw std::invalid_argument(
        "[LowAltitudeDryden] height must be in [3.048, 304.8] m (10-1000 ft, the model's "
        "range), got " +
        std::to_string(height));
  }
  const double h_ft = height / kFeet;
  const double k = 0.177 + 0.000823 * h_ft;
  DrydenSettings s;
  s.length_scale = Vec3(h_ft / std::pow(k, 1.2), h_ft / std::pow(k, 1.2), h_ft) * kFeet;
  const double sigma_w = 0.1 * w20;
  s.sigma = Vec3(sigma_w / std::pow(k, 0.4), sigma_w / std::pow(k, 0.4), sigma_w);
  s.airspeed = airspeed;
  s.Validate();
  return s;
}

double DrydenSpectrum(const DrydenSettings& s, int axis, double omega) {
  const double l = s.length_scale[axis], v = s.airspeed, sg = s.sigma[axis];
  const double x = l * omega / v;
  if (axis == 0) return sg * sg * (2.0 * l / (M_PI * v)) / (1.0 + x * x);
  return sg * sg * (l / (M_PI * v)) * (1.0 + 3.0 * x * x) / ((1.0 + x * x) * (1.0 + x * x));
}

double DrydenAutocorrelation(const DrydenSettings& s, int axis, double tau) {
  const double a = s.airspeed * std::abs(tau) / s.length_scale[axis];
  const double var = s.sigma[axis] * s.sigma[axis];
  if (axis == 0) return var * std::exp(-a);
  return var * (1.0 - 0.5 * a) * std::exp(-a);
}

DrydenTurbulence::DrydenTurbulence(const DrydenSettings& settings, double dt, std::uint64_t seed)
    : s_(settings) {
  s_.Validate();
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    throw std::invalid_argument("[DrydenTurbulence] dt must be > 0");
  }
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    0xD7D3u};
  rng_.seed(seq);
  // u: first order, an Ornstein-Uhlenbeck process with variance sigma_u^2.
  const double tu = s_.length_scale.x() / s_.airspeed;
  phi_u_ = std::exp(-dt / tu);
  sd_u_ = s_.sigma.x() * std::sqrt(1.0 - phi_u_ * phi_u_);
  u_ = s_.sigma.x() * normal_(rng_);
  // v, w: y1' = (xi - y1) / T, y2' = (y1 - y2) / T, output K (sqrt(3) y1 + (1 - sqrt(3)) y2)
  // = K (1 + sqrt(3) T s) / (1 + T s)^2 xi, K = sigma sqrt(L / (pi V)); xi has one-sided
  // spectral density 1, i.e. E[xi(t) xi(t')] = pi delta(t - t').
  const double q = M_PI;
  for (int k = 0; k < 2; ++k) {
    const int axis = k + 1;
    const double l = s_.length_scale[axis];
    const double t = l / s_.airspeed;
    const double e = std::exp(-dt / t);
    phi_[k] << e, 0.0, e * dt / t, e;
    // Q = q / T^2 int_0^dt exp(-2 tau / T) [1, tau / T; tau / T, tau^2 / T^2] d tau.
    const double a = 2.0 / t;
    const double ea = std::exp(-a * dt);
    const double i0 = (1.0 - ea) / a;
    const double i1 = (1.0 - ea * (1.0 + a * dt)) / (a * a);
    const double i2 = (2.0 - ea * (a * a * dt * dt + 2.0 * a * dt + 2.0)) / (a * a * a);
    Eigen::Matrix2d qd;
    qd << i0, i1 / t, i1 / t, i2 / (t * t);
    qd *= q / (t * t);
    chol_[k] = Eigen::LLT<Eigen::Matrix2d>(qd).matrixL();
    c_[k] = s_.sigma[axis] * std::sqrt(l / (M_PI * s_.airspeed)) *
            Eigen::Vector2d(std::sqrt(3.0), 1.0 - std::sqrt(3.0));
    const Eigen::Matrix2d p = StationaryCovariance(axis);
    const Eigen::Matrix2d lp = Eigen::LLT<Eigen::Matrix2d>(p).matrixL();
    x_[k] = lp * Eigen::Vector2d(normal_(rng_), normal_(rng_));
  }
  value_ = Vec3(u_, c_[0].dot(x_[0]), c_[1].dot(x_[1]));
}

Eigen::Matrix2d DrydenTurbulence::StationaryCovariance(int axis) const {
  // Continuous Lyapunov A P + P A^T + q B B^T = 0 with A = [-1 0; 1 -1] / T, B = (1 / T, 0):
  // P = q / T [1/2 1/4; 1/4 1/4].
  const double t = s_.length_scale[axis] / s_.airspeed;
  Eigen::Matrix2d p;
  p << 0.5, 0.25, 0.25, 0.25;
  return (M_PI / t) * p;
}

const Vec3& DrydenTurbulence::Step() {
  u_ = phi_u_ * u_ + sd_u_ * normal_(rng_);
  value_.x() = u_;
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector2d n(normal_(rng_), normal_(rng_));
    x_[k] = phi_[k] * x_[k] + chol_[k] * n;
    value_[k + 1] = c_[k].dot(x_[k]);
  }
  return value_;
}

}  // namespace fnmpc::sim

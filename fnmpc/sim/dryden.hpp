// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <random>

#include "fnmpc/core/types.hpp"

/// Atmospheric turbulence with the Dryden spectra of MIL-F-8785C (sec. 3.7.2) and
/// MIL-HDBK-1797 (appendix A, "Dryden form"), for the simulator's wind (docs/simulator.md,
/// "Wind"). No files, no allocation after construction.
namespace fnmpc::sim {

/// Intensities and scale lengths of the three components (u along the mean wind, v lateral,
/// w vertical).
struct DrydenSettings {
  Vec3 sigma = Vec3::Zero();              ///< standard deviations sigma_u, sigma_v, sigma_w [m/s]
  Vec3 length_scale{200.0, 200.0, 50.0};  ///< L_u, L_v, L_w [m]
  /// Speed that converts the spatial spectra to time (Taylor's frozen turbulence):
  /// the mean airspeed V [m/s] (the mean wind for a hovering vehicle).
  double airspeed = 1.0;

  /// Throws std::invalid_argument on negative sigma, non-positive L or V.
  void Validate() const;
};

/// MIL-F-8785C low-altitude model (h < 1000 ft, in feet there; here converted to metres):
/// L_w = h, L_u = L_v = h / (0.177 + 0.000823 h)^1.2, sigma_w = 0.1 W20,
/// sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4, with W20 the wind speed at 20 ft.
/// `height` [m] must lie in [3.048, 304.8] m (10 to 1000 ft, the model's range) and w20 >= 0.
DrydenSettings LowAltitudeDryden(double w20, double height, double airspeed);

/// One-sided power spectral densities [ (m/s)^2 / (rad/s) ] of MIL-HDBK-1797 in temporal
/// frequency omega [rad/s]: variance = integral over omega in [0, inf).
///   Phi_u(w) = sigma_u^2 (2 L_u / (pi V)) / (1 + (L_u w / V)^2)
///   Phi_v(w) = sigma_v^2 (L_v / (pi V)) (1 + 3 (L_v w / V)^2) / (1 + (L_v w / V)^2)^2
double DrydenSpectrum(const DrydenSettings& s, int axis, double omega);
/// Autocorrelation of the same spectra at lag tau [s]:
///   R_u(tau) = sigma_u^2 exp(-V tau / L_u),
///   R_v(tau) = sigma_v^2 (1 - V tau / (2 L_v)) exp(-V tau / L_v)   (and w like v).
double DrydenAutocorrelation(const DrydenSettings& s, int axis, double tau);

/// Exact discrete-time realisation of the Dryden shaping filters
///   H_u(s) = sigma_u sqrt(2 L_u / (pi V)) / (1 + T_u s),
///   H_v(s) = sigma_v sqrt(L_v / (pi V)) (1 + sqrt(3) T_v s) / (1 + T_v s)^2,   T = L / V,
/// driven by white noise of one-sided spectral density 1 (the handbook's convention), sampled
/// at a fixed step: each filter's state transition and process-noise covariance are the
/// closed-form integrals over one step, so the sampled sequence has exactly the
/// autocorrelation above at multiples of the step. Started in its stationary distribution.
class DrydenTurbulence {
 public:
  DrydenTurbulence(const DrydenSettings& settings, double dt, std::uint64_t seed);
  /// Advances one step; returns the gust (u, v, w) [m/s] in the wind frame.
  const Vec3& Step();
  [[nodiscard]] const Vec3& value() const { return value_; }
  /// Stationary covariance of the filter state of axis 1 or 2 (for the tests): the output
  /// variance is c^T P c with c = K (sqrt(3), 1 - sqrt(3)).
  [[nodiscard]] Eigen::Matrix2d StationaryCovariance(int axis) const;

 private:
  DrydenSettings s_;
  double phi_u_ = 0.0, sd_u_ = 0.0;
  Eigen::Matrix2d phi_[2];   // v and w: state transition over one step
  Eigen::Matrix2d chol_[2];  // Cholesky factor of the process noise over one step
  Eigen::Vector2d c_[2];     // output map
  Eigen::Vector2d x_[2];     // state
  double u_ = 0.0;
  Vec3 value_ = Vec3::Zero();
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace fnmpc::sim

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sysid/propulsion.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fnmpc::sysid {
namespace {

// Least squares y = a x through the origin; returns a and writes the RMS residual and the
// standard error of a, sqrt(s^2 / sum x^2) with s^2 = SS_res / (n - 1).
double ThroughOrigin(const std::vector<double>& x, const std::vector<double>& y, double* rms,
                     double* std_error) {
  double xx = 0.0, xy = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    xx += x[i] * x[i];
    xy += x[i] * y[i];
  }
  if (!(xx > 0.0)) throw std::invalid_argument("[FitPropulsion] all rotor speeds are zero");
  const double a = xy / xx;
  double ss = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) ss += (y[i] - a * x[i]) * (y[i] - a * x[i]);
  *rms = std::sqrt(ss / static_cast<double>(x.size()));
  *std_error = std::sqrt(ss / static_cast<double>(x.size() - 1) / xx);
  return a;
}

}  // namespace

PropulsionFit FitPropulsion(const BenchData& b) {
  const std::size_t n = b.throttle.size();
  if (b.voltage.size() != n || b.rpm.size() != n || b.thrust.size() != n || b.torque.size() != n) {
    throw std::invalid_argument("[FitPropulsion] bench columns differ in length");
  }
  if (n < 10) {
    throw std::invalid_argument("[FitPropulsion] need at least 10 bench samples, got " +
                                std::to_string(n));
  }
  PropulsionFit fit;
  fit.samples = static_cast<int>(n);
  std::vector<double> rpm2(n);
  for (std::size_t i = 0; i < n; ++i) rpm2[i] = b.rpm[i] * b.rpm[i];
  fit.thrust_constant =
      ThroughOrigin(rpm2, b.thrust, &fit.thrust_rms, &fit.thrust_constant_std_error);
  fit.torque_constant =
      ThroughOrigin(rpm2, b.torque, &fit.torque_rms, &fit.torque_constant_std_error);

  // Polynomial: columns f^i V^j (i + j <= 3), each scaled to unit norm for conditioning.
  std::vector<std::size_t> rows;
  for (std::size_t k = 0; k < n; ++k) {
    if (b.thrust[k] > 0.0) rows.push_back(k);
  }
  constexpr int kTerms = 10;
  if (rows.size() < 2 * kTerms) {
    throw std::invalid_argument("[FitPropulsion] need at least 20 samples with thrust > 0, got " +
                                std::to_string(rows.size()));
  }
  fit.polynomial_samples = static_cast<int>(rows.size());
  Eigen::MatrixXd A(rows.size(), kTerms);
  Eigen::VectorXd y(rows.size());
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const double f = b.thrust[rows[r]], v = b.voltage[rows[r]];
    int col = 0;
    for (int i = 0; i <= 3; ++i) {
      for (int j = 0; i + j <= 3; ++j) A(r, col++) = std::pow(f, i) * std::pow(v, j);
    }
    y[r] = b.throttle[rows[r]];
  }
  const Eigen::VectorXd scale = A.colwise().norm().transpose();
  for (int c = 0; c < kTerms; ++c) A.col(c) /= scale[c];
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  qr.setThreshold(1e-12);
  if (qr.rank() < kTerms) {
    throw std::invalid_argument(
        "[FitPropulsion] the bench data do not determine the cubic polynomial (rank " +
        std::to_string(qr.rank()) + " of 10): vary both throttle and voltage");
  }
  const Eigen::VectorXd coef = qr.solve(y).cwiseQuotient(scale);
  int col = 0;
  for (int i = 0; i <= 3; ++i) {
    for (int j = 0; i + j <= 3; ++j) fit.throttle.c(i, j) = coef[col++];
  }
  double ss = 0.0, fmax = 0.0;
  for (std::size_t r : rows) fmax = std::max(fmax, b.thrust[r]);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const double e =
        fit.throttle.Throttle(b.thrust[rows[r]], b.voltage[rows[r]]) - b.throttle[rows[r]];
    ss += e * e;
    fit.throttle_max_abs = std::max(fit.throttle_max_abs, std::abs(e));
    if (b.thrust[rows[r]] >= 0.2 * fmax) {
      fit.throttle_max_abs_envelope = std::max(fit.throttle_max_abs_envelope, std::abs(e));
    }
  }
  fit.throttle_rms = std::sqrt(ss / static_cast<double>(rows.size()));
  return fit;
}

}  // namespace fnmpc::sysid

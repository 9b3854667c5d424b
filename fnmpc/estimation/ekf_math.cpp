// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/estimation/ekf_math.hpp"

#include <stdexcept>
#include <string>

namespace fnmpc::estimation {
namespace {

double NormalSurvival(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }

}  // namespace

double Chi2Survival(double x, int dof) {
  if (x <= 0.0) return 1.0;
  if (dof > 200) {
    // Wilson-Hilferty: (X/k)^(1/3) is nearly normal with mean 1 - 2/(9k), var 2/(9k).
    const double k = dof;
    const double z = (std::cbrt(x / k) - (1.0 - 2.0 / (9.0 * k))) / std::sqrt(2.0 / (9.0 * k));
    return NormalSurvival(z);
  }
  const double h = 0.5 * x;
  double sum = 0.0;
  if (dof % 2 == 0) {
    // Q = exp(-h) sum_{i<dof/2} h^i / i!
    double term = std::exp(-h);
    for (int i = 0; i < dof / 2; ++i) {
      sum += term;
      term *= h / (i + 1);
    }
    return sum;
  }
  // Q = erfc(sqrt(h)) + exp(-h) sum_{i<(dof-1)/2} h^(i+1/2) / Gamma(i+3/2)
  double term = std::exp(-h) * std::sqrt(h) / std::tgamma(1.5);
  for (int i = 0; i < (dof - 1) / 2; ++i) {
    sum += term;
    term *= h / (i + 1.5);
  }
  return std::erfc(std::sqrt(h)) + sum;
}

double Chi2Quantile(double p, int dof) {
  if (!(p > 0.0 && p < 1.0)) {
    throw std::invalid_argument("[Chi2Quantile] probability must be in (0, 1), got " +
                                std::to_string(p));
  }
  if (dof < 1) {
    throw std::invalid_argument("[Chi2Quantile] dof must be >= 1, got " + std::to_string(dof));
  }
  // Bisection on the monotone survival function.
  const double q = 1.0 - p;
  double lo = 0.0;
  double hi = dof + 10.0;
  while (Chi2Survival(hi, dof) > q) hi *= 2.0;
  for (int it = 0; it < 200 && hi - lo > 1e-12 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    if (Chi2Survival(mid, dof) > q) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return 0.5 * (lo + hi);
}

void RotationZyxPartials(const Vec3& euler, Mat3* R, std::array<Mat3, 3>* dR) {
  const double cf = std::cos(euler.x()), sf = std::sin(euler.x());
  const double ct = std::cos(euler.y()), st = std::sin(euler.y());
  const double cp = std::cos(euler.z()), sp = std::sin(euler.z());
  Mat3 rx, ry, rz, drx, dry, drz;
  rx << 1, 0, 0, 0, cf, -sf, 0, sf, cf;
  ry << ct, 0, st, 0, 1, 0, -st, 0, ct;
  rz << cp, -sp, 0, sp, cp, 0, 0, 0, 1;
  drx << 0, 0, 0, 0, -sf, -cf, 0, cf, -sf;
  dry << -st, 0, ct, 0, 0, 0, -ct, 0, -st;
  drz << -sp, -cp, 0, cp, -sp, 0, 0, 0, 0;
  const Mat3 rzy = rz * ry;
  *R = rzy * rx;
  (*dR)[0] = rzy * drx;
  (*dR)[1] = rz * dry * rx;
  (*dR)[2] = drz * ry * rx;
}

}  // namespace fnmpc::estimation

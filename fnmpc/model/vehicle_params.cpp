// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/model/vehicle_params.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace fnmpc::model {

double ThrottlePolynomial::Throttle(double f, double voltage) const {
  double sum = 0.0;
  double fi = 1.0;
  for (int i = 0; i <= 3; ++i) {
    double vj = 1.0;
    for (int j = 0; i + j <= 3; ++j) {
      sum += c(i, j) * fi * vj;
      vj *= voltage;
    }
    fi *= f;
  }
  return sum;
}

double ThrottlePolynomial::DThrottleDThrust(double f, double voltage) const {
  double sum = 0.0;
  double fim1 = 1.0;  // f^(i-1)
  for (int i = 1; i <= 3; ++i) {
    double vj = 1.0;
    for (int j = 0; i + j <= 3; ++j) {
      sum += i * c(i, j) * fim1 * vj;
      vj *= voltage;
    }
    fim1 *= f;
  }
  return sum;
}

double ThrottlePolynomial::Thrust(double throttle, double voltage, double f_max) const {
  // Bracket on a grid, then bisection + Newton: the cubic may be non-monotone far
  // outside the identified envelope, so take the smallest root in [0, f_max].
  constexpr int kGrid = 64;
  double f_lo = 0.0;
  double r_lo = Throttle(0.0, voltage) - throttle;
  if (r_lo == 0.0) return 0.0;
  for (int k = 1; k <= kGrid; ++k) {
    const double f_hi = f_max * k / kGrid;
    const double r_hi = Throttle(f_hi, voltage) - throttle;
    if ((r_lo < 0.0) != (r_hi < 0.0) || r_hi == 0.0) {
      double a = f_lo, b = f_hi, ra = r_lo;
      for (int it = 0; it < 60 && b - a > 1e-12; ++it) {
        const double m = 0.5 * (a + b);
        const double rm = Throttle(m, voltage) - throttle;
        if ((ra < 0.0) == (rm < 0.0)) {
          a = m;
          ra = rm;
        } else {
          b = m;
        }
      }
      return 0.5 * (a + b);
    }
    f_lo = f_hi;
    r_lo = r_hi;
  }
  return std::nan("");
}

namespace {
void RequirePositive(double v, const char* name) {
  if (!(v > 0.0) || !std::isfinite(v)) {
    throw std::invalid_argument(std::string("[VehicleParams] ") + name +
                                " must be finite and > 0, got " + std::to_string(v));
  }
}
}  // namespace

std::string UnrealisableInertia(const Eigen::Vector3d& inertia) {
  static const char* const kAxis[3] = {"Ixx", "Iyy", "Izz"};
  for (int a = 0; a < 3; ++a) {
    if (!(inertia[a] > 0.0) || !std::isfinite(inertia[a])) {
      return std::string(kAxis[a]) + " = " + std::to_string(inertia[a]) +
             " must be finite and > 0 (positive definite)";
    }
  }
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    if (inertia[b] + inertia[c] < inertia[a]) {
      std::ostringstream os;
      os.precision(6);
      os << kAxis[a] << " = " << inertia[a] << " exceeds " << kAxis[b] << " + " << kAxis[c] << " = "
         << inertia[b] + inertia[c]
         << ": no rigid body has these principal moments (triangle inequality)";
      return os.str();
    }
  }
  return "";
}

void VehicleParams::Validate() const {
  RequirePositive(mass, "mass");
  for (int i = 0; i < 3; ++i) {
    RequirePositive(inertia[i], "inertia");
    RequirePositive(attitude_time_constant[i], "attitude.time_constant");
    RequirePositive(attitude_gain[i], "attitude.gain");
    if (!(attitude_kp[i] >= 0.0) || !(attitude_kd[i] >= 0.0)) {
      throw std::invalid_argument("[VehicleParams] attitude_pd gains must be >= 0");
    }
  }
  if (const std::string why = UnrealisableInertia(inertia); !why.empty()) {
    throw std::invalid_argument("[VehicleParams] inertia: " + why);
  }
  RequirePositive(thrust_constant, "thrust_constant");
  RequirePositive(torque_constant, "torque_constant");
  RequirePositive(arm_length, "arm_length");
  RequirePositive(bias.thrust_scale, "bias.thrust");
  if (!throttle.c.allFinite()) {
    throw std::invalid_argument("[VehicleParams] throttle_polynomial has non-finite coefficients");
  }
}

}  // namespace fnmpc::model

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/throttle_map.hpp"

#include <algorithm>
#include <cmath>

#include "fnmpc/core/types.hpp"

namespace fnmpc::formation {

double ThrustToThrottle(const model::ThrottlePolynomial& poly, double thrust, double voltage) {
  if (!std::isfinite(thrust) || !std::isfinite(voltage) || !(voltage > 0.0)) return kNaN;
  if (thrust <= 0.0) return 0.0;
  return std::clamp(poly.Throttle(thrust / 4.0, voltage), 0.0, 1.0);
}

double ThrottleToThrust(const model::ThrottlePolynomial& poly, double throttle, double voltage) {
  if (!std::isfinite(throttle) || !std::isfinite(voltage)) return kNaN;
  if (throttle <= poly.Throttle(0.0, voltage)) return 0.0;
  return 4.0 * poly.Thrust(throttle, voltage);
}

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <vector>

#include "fnmpc/core/rotation.hpp"

namespace fnmpc::sysid {

/// Continuous version of a sampled angle [rad]: each sample is moved by a multiple of 2 pi
/// to within pi of its (unwrapped) predecessor. O(1) per sample (WrapAngle, std::remainder),
/// so an absurd value (1e17 rad) cannot make it loop; it stays finite.
inline std::vector<double> UnwrapAngles(std::vector<double> a) {
  for (std::size_t i = 1; i < a.size(); ++i) a[i] = a[i - 1] + WrapAngle(a[i] - a[i - 1]);
  return a;
}

/// The angle `a` moved by a multiple of 2 pi to within pi of `near` [rad]. O(1).
inline double UnwrapNear(double a, double near) { return near + WrapAngle(a - near); }

}  // namespace fnmpc::sysid

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/frame_conversions.hpp"

#include <cmath>

#include "fnmpc/core/rotation.hpp"

namespace fnmpc::mavlink {
namespace {

// R_ENU_NED = [0 1 0; 1 0 0; 0 0 -1]: a half turn about (1, 1, 0)/sqrt(2).
const Eigen::Quaterniond kEnuNed(0.0, M_SQRT1_2, M_SQRT1_2, 0.0);
// R_FRD_FLU = diag(1, -1, -1): a half turn about x.
const Eigen::Quaterniond kFrdFlu(0.0, 1.0, 0.0, 0.0);

// Both maps have the same form: they are involutions (R_NED_ENU = R_ENU_NED, and likewise
// for the body frames).
Eigen::Quaterniond Swap(const Eigen::Quaterniond& q) { return kEnuNed * q * kFrdFlu; }
Vec3 SwapEuler(const Vec3& rpy) { return {rpy.x(), -rpy.y(), WrapAngle(M_PI_2 - rpy.z())}; }

}  // namespace

Eigen::Quaterniond NedFrdToEnuFlu(const Eigen::Quaterniond& q_ned_frd) { return Swap(q_ned_frd); }
Eigen::Quaterniond EnuFluToNedFrd(const Eigen::Quaterniond& q_enu_flu) { return Swap(q_enu_flu); }
Vec3 EulerNedFrdToEnuFlu(const Vec3& rpy_ned_frd) { return SwapEuler(rpy_ned_frd); }
Vec3 EulerEnuFluToNedFrd(const Vec3& rpy_enu_flu) { return SwapEuler(rpy_enu_flu); }

}  // namespace fnmpc::mavlink

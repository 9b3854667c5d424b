// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>

#include "fnmpc/core/types.hpp"

/// A follower's estimate of a neighbour's collective thrust from its estimated motion (the
/// wake-aware prediction, compensation level `wake`, needs the thrust of the neighbour whose wake
/// it predicts: estimated from its motion, or shared in cooperative mode).
///
/// Why this formula: a multirotor's only large force besides gravity is its collective thrust
/// along its body z axis, so Newton's second law m a = T R e_z - m g e_z + f gives, with the
/// external force f (drag, wakes) neglected, T = m ||a + g e_z|| (e.g. Mellinger and Kumar,
/// "Minimum snap trajectory generation and control for quadrotors", ICRA 2011, eq. 5: the
/// thrust direction and magnitude follow from the acceleration). The mass is the follower's own
/// vehicle file's (the formation's vehicles share one file unless a scenario says otherwise;
/// docs/scenarios.md `controller.compensation`). The acceleration is the neighbour filter's
/// estimate (neighbour_acceleration.hpp), present in every configuration.
namespace fnmpc::formation {

/// Why a thrust estimate left the formula's value (ControlOutput::neighbour_thrust_bound).
enum class ThrustBound : int {
  kNone = 0,        ///< m ||a + g e_z|| within [0, max]
  kNonFinite = 1,   ///< the acceleration or mass was not finite: hover thrust m g
  kUpsideDown = 2,  ///< a_z < -g: the thrust would point down (faster than free fall): 0
  kAboveMax = 3,    ///< above the most any vehicle of the formation can be commanded: max
};
inline constexpr const char* kThrustBoundNames[] = {"none", "non_finite", "upside_down",
                                                    "above_max"};
inline const char* ToString(ThrustBound b) { return kThrustBoundNames[static_cast<int>(b)]; }

struct ThrustEstimate {
  double thrust = kNaN;  ///< [N], always finite for a finite mass and max_thrust
  ThrustBound bound = ThrustBound::kNone;
};

/// T = mass ||acc + g e_z|| [N] for a vehicle of `mass` [kg] with acceleration `acc` [m/s^2]
/// ({n} or {m} axes, z up), bounded to [0, max_thrust]: a non-finite input gives the hover
/// thrust mass g, an acceleration downward beyond free fall gives 0 (a multirotor's thrust
/// cannot point down), above max_thrust gives max_thrust; `bound` says which.
inline ThrustEstimate ThrustFromAcceleration(double mass, const Vec3& acc, double max_thrust) {
  if (!acc.allFinite() || !std::isfinite(mass)) return {mass * kGravity, ThrustBound::kNonFinite};
  const Vec3 specific(acc.x(), acc.y(), acc.z() + kGravity);  // thrust per mass, R e_z T / m
  if (specific.z() < 0.0) return {0.0, ThrustBound::kUpsideDown};
  const double thrust = mass * specific.norm();
  if (thrust > max_thrust) return {max_thrust, ThrustBound::kAboveMax};
  return {thrust, ThrustBound::kNone};
}

}  // namespace fnmpc::formation

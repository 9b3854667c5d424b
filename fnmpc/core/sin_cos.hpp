// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>

namespace fnmpc {

/// sin(x) and cos(x) together. For |x| <= pi/4, which holds for the roll and pitch in normal
/// flight (the attitude references are bounded by max_attitude_ref, default 0.35 rad) and for
/// a yaw near zero, by their Taylor series about 0 in Horner form,
/// inline: the terms up to x^17 (sine) and x^16 (cosine), whose truncation error, below
/// x^19 / 19! and x^18 / 18! (1e-19 and 2e-18 at pi/4), is far below the half unit in the
/// last place that the final rounding adds; the result is within 1 ulp of std::sin and
/// std::cos (tests/core/sin_cos_test.cpp). Elsewhere it is std::sin and std::cos. Why: the
/// model's RK4 sensitivities evaluate the body z axis eight times per shooting interval,
/// three library sincos calls each, about 15 % of a follower's control step
/// (docs/benchmarks.md); the inline series is a few dozen fused multiply-adds and no call.
inline void SinCos(double x, double* s, double* c) {
  constexpr double kQuarterPi = 0.78539816339744830962;
  if (!(std::abs(x) <= kQuarterPi)) {  // (NaN too: std::sin and std::cos return NaN)
    *s = std::sin(x);
    *c = std::cos(x);
    return;
  }
  // 1/n! for the odd (sine) and even (cosine) powers.
  constexpr double f3 = 1.0 / 6.0, f5 = f3 / 20.0, f7 = f5 / 42.0, f9 = f7 / 72.0, f11 = f9 / 110.0,
                   f13 = f11 / 156.0, f15 = f13 / 210.0, f17 = f15 / 272.0;
  constexpr double f2 = 0.5, f4 = f2 / 12.0, f6 = f4 / 30.0, f8 = f6 / 56.0, f10 = f8 / 90.0,
                   f12 = f10 / 132.0, f14 = f12 / 182.0, f16 = f14 / 240.0;
  const double x2 = x * x;
  const double ps =
      -f3 + x2 * (f5 + x2 * (-f7 + x2 * (f9 + x2 * (-f11 + x2 * (f13 + x2 * (-f15 + x2 * f17))))));
  const double pc =
      -f2 + x2 * (f4 + x2 * (-f6 + x2 * (f8 + x2 * (-f10 + x2 * (f12 + x2 * (-f14 + x2 * f16))))));
  *s = x + (x * x2) * ps;
  *c = 1.0 + x2 * pc;
}

}  // namespace fnmpc

// SPDX-License-Identifier: BSD-3-Clause
#pragma once
// Central-difference Jacobian of f: R^N -> R^M at x, for the tests that check hand-derived
// derivatives (step 1e-6).

#include "fnmpc/core/types.hpp"

namespace fnmpc::testing {

template <int N, class F>
auto NumericJacobian(const Vec<N>& x, F&& f) {
  using Out = decltype(f(x));
  Mat<Out::RowsAtCompileTime, N> J;
  for (int i = 0; i < N; ++i) {
    Vec<N> xp = x, xm = x;
    xp(i) += 1e-6;
    xm(i) -= 1e-6;
    J.col(i) = (f(xp) - f(xm)) / 2e-6;
  }
  return J;
}

}  // namespace fnmpc::testing

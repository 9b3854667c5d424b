// SPDX-License-Identifier: BSD-3-Clause
// The iterate of an RtiSolver (acados' "solution"): the primal guess, the last step and
// the multipliers recovered for the KKT value.
#pragma once

#include <vector>

#include "fnmpc/core/types.hpp"

namespace fnmpc::rti {

template <class Problem>
struct Iterate {
  using X = Vec<Problem::kNx>;
  using U = Vec<Problem::kNu>;

  explicit Iterate(int horizon)
      : x(horizon + 1, X::Zero()),
        u(horizon, U::Zero()),
        dx(horizon + 1, X::Zero()),
        du(horizon, U::Zero()),
        lambda(horizon + 1, X::Zero()),
        mu(horizon + 1, X::Zero()) {}

  std::vector<X> x;   ///< states x_0..x_N
  std::vector<U> u;   ///< inputs u_0..u_N-1
  std::vector<X> dx;  ///< the last step (dx_k, du_k)
  std::vector<U> du;
  /// Dynamics multipliers and the state-bound multipliers summed per node (ComputeKkt).
  std::vector<X> lambda, mu;
};

}  // namespace fnmpc::rti

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"

namespace fnmpc {

/// Explicit RK4 over one interval of length `dt` [s] split in `steps` equal steps, for any
/// model given as a callable `flow(x, u, &f, &fx, &fu)` that writes f = dx/dt (Nx) and, when
/// fx (Nx x Nx) and fu (Nx x Nu) are not null, its Jacobians (entries it does not write stay
/// zero). Returns x(dt); when A and B are given, also the exact sensitivities of the discrete
/// map (every entry written). The model-agnostic integrator for problems of the RTI solver's
/// contract (docs/rti.md); the quadrotor models use the structured model::Rk4
/// (fnmpc/model/rk4.hpp), which exploits the sparsity of their Jacobians.
template <int Nx, int Nu, class Flow>
Vec<Nx> IntegrateRk4(const Flow& flow, const Vec<Nx>& x0, const Vec<Nu>& u, double dt, int steps,
                     Mat<Nx, Nx>* A = nullptr, Mat<Nx, Nu>* B = nullptr) {
  using X = Vec<Nx>;
  const double h = dt / steps;
  X x = x0;
  X k1, k2, k3, k4;
  if (A == nullptr || B == nullptr) {
    Mat<Nx, Nx>* no_fx = nullptr;
    Mat<Nx, Nu>* no_fu = nullptr;
    for (int s = 0; s < steps; ++s) {
      flow(x, u, &k1, no_fx, no_fu);
      flow(X(x + 0.5 * h * k1), u, &k2, no_fx, no_fu);
      flow(X(x + 0.5 * h * k2), u, &k3, no_fx, no_fu);
      flow(X(x + h * k3), u, &k4, no_fx, no_fu);
      x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    return x;
  }
  // Sensitivities S = [d x / d x0 | d x / d u]; each stage derivative is
  // dk = f_x (S + c h dk_prev) + [0 | f_u].
  using MS = Mat<Nx, Nx + Nu>;
  MS S = MS::Zero();
  S.template leftCols<Nx>().setIdentity();
  MS dk1, dk2, dk3, dk4;
  Mat<Nx, Nx> fx = Mat<Nx, Nx>::Zero();
  Mat<Nx, Nu> fu = Mat<Nx, Nu>::Zero();
  auto stage = [&](const X& xs, const MS& ts, X* k, MS* dk) {
    flow(xs, u, k, &fx, &fu);
    dk->noalias() = fx * ts;
    dk->template rightCols<Nu>() += fu;
  };
  for (int s = 0; s < steps; ++s) {
    stage(x, S, &k1, &dk1);
    stage(X(x + 0.5 * h * k1), MS(S + (0.5 * h) * dk1), &k2, &dk2);
    stage(X(x + 0.5 * h * k2), MS(S + (0.5 * h) * dk2), &k3, &dk3);
    stage(X(x + h * k3), MS(S + h * dk3), &k4, &dk4);
    x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    S += (h / 6.0) * (dk1 + 2.0 * dk2 + 2.0 * dk3 + dk4);
  }
  *A = S.template leftCols<Nx>();
  *B = S.template rightCols<Nu>();
  return x;
}

}  // namespace fnmpc

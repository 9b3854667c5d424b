// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/types.hpp"
#include "fnmpc/model/quadrotor_model.hpp"

namespace fnmpc::model {

/// Explicit RK4 over one shooting interval of length `dt` [s] split in `steps` equal
/// steps, for any model with static FlowJacobian(x, u, psi_ref, params, f, fx, fu).
/// Returns x(dt); when A and B are given, also the exact sensitivities of the discrete
/// map, A = d x(dt) / d x(0) and B = d x(dt) / d u (forward sensitivity propagation
/// through the RK4 stages: the derivative of the discrete map, not of the ODE).
template <class Model>
Vec<Model::kNx> Rk4(const Vec<Model::kNx>& x0, const Vec<Model::kNu>& u, double psi_ref,
                    const AttitudeModelParams& m, double dt, int steps,
                    Mat<Model::kNx, Model::kNx>* A = nullptr,
                    Mat<Model::kNx, Model::kNu>* B = nullptr) {
  constexpr int nx = Model::kNx, nu = Model::kNu;
  using X = Vec<nx>;
  using MX = Mat<nx, nx>;
  using MU = Mat<nx, nu>;
  const double h = dt / steps;
  X x = x0;
  const bool sens = A != nullptr && B != nullptr;
  X k1, k2, k3, k4;
  MX fx;
  MU fu;
  if (!sens) {
    for (int s = 0; s < steps; ++s) {
      k1 = Model::template Flow<double>(x, u, psi_ref, m);
      k2 = Model::template Flow<double>(X(x + 0.5 * h * k1), u, psi_ref, m);
      k3 = Model::template Flow<double>(X(x + 0.5 * h * k2), u, psi_ref, m);
      k4 = Model::template Flow<double>(X(x + h * k3), u, psi_ref, m);
      x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    return x;
  }
  // Sensitivities of the current state w.r.t. (x0, u) and of the stages.
  MX Sx = MX::Identity();
  MU Su = MU::Zero();
  MX dk1x, dk2x, dk3x, dk4x, tx;
  MU dk1u, dk2u, dk3u, dk4u, tu;
  for (int s = 0; s < steps; ++s) {
    Model::FlowJacobian(x, u, psi_ref, m, &k1, &fx, &fu);
    if (s == 0) {
      dk1x = fx;  // Sx = I on the first step
      dk1u = fu;
    } else {
      dk1x.noalias() = fx * Sx;
      dk1u.noalias() = fx * Su;
      dk1u += fu;
    }
    Model::FlowJacobian(X(x + 0.5 * h * k1), u, psi_ref, m, &k2, &fx, &fu);
    tx = Sx + 0.5 * h * dk1x;
    tu = Su + 0.5 * h * dk1u;
    dk2x.noalias() = fx * tx;
    dk2u.noalias() = fx * tu;
    dk2u += fu;
    Model::FlowJacobian(X(x + 0.5 * h * k2), u, psi_ref, m, &k3, &fx, &fu);
    tx = Sx + 0.5 * h * dk2x;
    tu = Su + 0.5 * h * dk2u;
    dk3x.noalias() = fx * tx;
    dk3u.noalias() = fx * tu;
    dk3u += fu;
    Model::FlowJacobian(X(x + h * k3), u, psi_ref, m, &k4, &fx, &fu);
    tx = Sx + h * dk3x;
    tu = Su + h * dk3u;
    dk4x.noalias() = fx * tx;
    dk4u.noalias() = fx * tu;
    dk4u += fu;
    x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    Sx += (h / 6.0) * (dk1x + 2.0 * dk2x + 2.0 * dk3x + dk4x);
    Su += (h / 6.0) * (dk1u + 2.0 * dk2u + 2.0 * dk3u + dk4u);
  }
  *A = Sx;
  *B = Su;
  return x;
}

}  // namespace fnmpc::model

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <type_traits>
#include <utility>

#include "fnmpc/core/types.hpp"
#include "fnmpc/model/quadrotor_model.hpp"

namespace fnmpc::model {

/// Explicit RK4 over one shooting interval of length `dt` [s] split in `steps` equal
/// steps, for any model with static Flow, FlowAndJacobian, MultiplyFx and AddFu.
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
  const double h = dt / steps;
  X x = x0;
  const bool sens = A != nullptr && B != nullptr;
  X k1, k2, k3, k4;
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
  // Sensitivities of the current state w.r.t. (x0, u), side by side: S = [Sx | Su].
  // Each stage derivative is dk = f_x (S + c h dk_prev) + [0 | f_u]; the structured
  // product MultiplyFx exploits the sparsity of f_x.
  using MS = Mat<nx, nx + nu>;
  MS S = MS::Zero();
  S.template leftCols<nx>().setIdentity();
  MS dk1, dk2, dk3, dk4, t;
  typename Model::Jacobian jac;
  auto stage = [&](const X& xs, const MS& ts, X* k, MS* dk) {
    Model::FlowAndJacobian(xs, u, psi_ref, m, k, &jac);
    Model::MultiplyFx(jac, ts, dk);
    auto du = dk->template rightCols<nu>();
    Model::AddFu(jac, &du);
  };
  for (int s = 0; s < steps; ++s) {
    stage(x, S, &k1, &dk1);
    t = S + (0.5 * h) * dk1;
    stage(X(x + 0.5 * h * k1), t, &k2, &dk2);
    t = S + (0.5 * h) * dk2;
    stage(X(x + 0.5 * h * k2), t, &k3, &dk3);
    t = S + h * dk3;
    stage(X(x + h * k3), t, &k4, &dk4);
    x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    S += (h / 6.0) * (dk1 + 2.0 * dk2 + 2.0 * dk3 + dk4);
  }
  *A = S.template leftCols<nx>();
  *B = S.template rightCols<nu>();
  return x;
}

/// Models whose RK4 interval map with sensitivities is derived by hand in structured form
/// (QuadrotorModel, FollowerModel): Model::Discretise. A detection trait, not a concept,
/// because the ROS nodes include this header from C++17 translation units (ROS 1's message
/// headers do not compile as C++20).
template <class Model>
using DiscretiseResult = decltype(Model::Discretise(
    std::declval<const Vec<Model::kNx>&>(), std::declval<const Vec<Model::kNu>&>(), 0.0,
    std::declval<const AttitudeModelParams&>(), 0.0, 1,
    std::declval<Mat<Model::kNx, Model::kNx>*>(), std::declval<Mat<Model::kNx, Model::kNu>*>()));
template <class Model, class = void>
struct HasStructuredDiscretisation : std::false_type {};
template <class Model>
struct HasStructuredDiscretisation<Model, std::void_t<DiscretiseResult<Model>>>
    : std::is_same<DiscretiseResult<Model>, Vec<Model::kNx>> {};

/// The RK4 interval map of Rk4 with its sensitivities A and B, by the model's structured
/// Discretise when it has one (then only the structural nonzeros of A and B are written:
/// the caller keeps the other entries zero), else by the generic Rk4 (writes all).
template <class Model>
Vec<Model::kNx> Discretise(const Vec<Model::kNx>& x0, const Vec<Model::kNu>& u, double psi_ref,
                           const AttitudeModelParams& m, double dt, int steps,
                           Mat<Model::kNx, Model::kNx>* A, Mat<Model::kNx, Model::kNu>* B) {
  if constexpr (HasStructuredDiscretisation<Model>::value) {
    return Model::Discretise(x0, u, psi_ref, m, dt, steps, A, B);
  } else {
    return Rk4<Model>(x0, u, psi_ref, m, dt, steps, A, B);
  }
}

}  // namespace fnmpc::model

// SPDX-License-Identifier: BSD-3-Clause
// The problem contract of RtiSolver<Problem> (docs/rti.md): detection traits that turn a
// missing member into a readable static_assert, and the optional structured products of a
// problem's model. C++17: the ROS nodes include the solver from C++17 units.
#pragma once

#include <type_traits>
#include <utility>

#include "fnmpc/core/eigen_abi.hpp"
#include "fnmpc/core/types.hpp"

namespace fnmpc::rti {

namespace detail {
/// Models with structured products with their transition matrix (Model::MultiplyTransition,
/// MultiplyTransitionRight and MultiplyTransitionTransposed, see QuadrotorModel). A detection
/// trait: the ROS nodes include this header from C++17 units.
template <class Model, class = void>
struct HasStructuredTransition : std::false_type {};
template <class Model>
struct HasStructuredTransition<
    Model,
    std::void_t<decltype(Model::MultiplyTransition(
                    std::declval<const Mat<Model::kNx, Model::kNx>&>(),
                    std::declval<const Vec<Model::kNx>&>(), std::declval<Vec<Model::kNx>*>())),
                decltype(Model::MultiplyTransitionRight(
                    std::declval<const Mat<1, Model::kNx>&>(),
                    std::declval<const Mat<Model::kNx, Model::kNx>&>(),
                    std::declval<Mat<1, Model::kNx>*>())),
                decltype(Model::MultiplyTransitionTransposed(
                    std::declval<const Mat<Model::kNx, Model::kNx>&>(),
                    std::declval<const Vec<Model::kNx>&>(), std::declval<Vec<Model::kNx>*>()))>>
    : std::true_type {};

// ---- The problem contract (docs/rti.md): detection traits for readable errors. ----
template <class T, class = void>
struct HasDims : std::false_type {};
template <class T>
struct HasDims<T, std::void_t<decltype(int{T::kNx}), decltype(int{T::kNu}), decltype(int{T::kNy}),
                              decltype(int{T::kNyN})>> : std::true_type {};
template <class T, class = void>
struct HasParams : std::false_type {};
template <class T>
struct HasParams<T, std::void_t<typename T::Params>> : std::true_type {};
template <class T, class = void>
struct HasDiscretise : std::false_type {};
template <class T>
struct HasDiscretise<
    T, std::void_t<decltype(Vec<T::kNx>(std::declval<const T&>().Discretise(
           std::declval<const Vec<T::kNx>&>(), std::declval<const Vec<T::kNu>&>(),
           std::declval<const typename T::Params&>(), 0.0, 1, std::declval<Mat<T::kNx, T::kNx>*>(),
           std::declval<Mat<T::kNx, T::kNu>*>())))>> : std::true_type {};
template <class T, class = void>
struct HasStageResidual : std::false_type {};
template <class T>
struct HasStageResidual<
    T, std::void_t<decltype(std::declval<const T&>().StageResidual(
           std::declval<const Vec<T::kNx>&>(), std::declval<const Vec<T::kNu>&>(),
           std::declval<const typename T::Params&>(), std::declval<Vec<T::kNy>*>(),
           std::declval<Mat<T::kNy, T::kNx>*>(), std::declval<Mat<T::kNy, T::kNu>*>()))>>
    : std::true_type {};
template <class T, class = void>
struct HasTerminalResidual : std::false_type {};
template <class T>
struct HasTerminalResidual<
    T, std::void_t<decltype(std::declval<const T&>().TerminalResidual(
           std::declval<const Vec<T::kNx>&>(), std::declval<const typename T::Params&>(),
           std::declval<Vec<T::kNyN>*>(), std::declval<Mat<T::kNyN, T::kNx>*>()))>>
    : std::true_type {};
/// Problem::Model when the problem names one (for its optional structured transition
/// products), else void.
template <class T, class = void>
struct ModelOf {
  using type = void;
};
template <class T>
struct ModelOf<T, std::void_t<typename T::Model>> {
  using type = typename T::Model;
};

/// Checks the problem contract before RtiSolver's body uses it, so that the first error a
/// compiler prints names the missing member. Each check is required by the next ones.
template <class Problem>
struct ProblemContract {
  static constexpr bool kDims = HasDims<Problem>::value;
  static_assert(kDims,
                "RtiSolver<Problem>: Problem must declare static constexpr int kNx, kNu, kNy, "
                "kNyN (state, input, stage residual and terminal residual sizes)");
  static constexpr bool kParams = kDims && HasParams<Problem>::value;
  static_assert(!kDims || kParams,
                "RtiSolver<Problem>: Problem must declare the type Params of its "
                "per-stage parameters (e.g. `struct Params {};` for none)");
  static constexpr bool kSizes =
      kParams && Problem::kNx >= 1 && Problem::kNu >= 1 && Problem::kNy >= 1 && Problem::kNyN >= 1;
  static_assert(!kParams || kSizes, "RtiSolver<Problem>: kNx, kNu, kNy and kNyN must be >= 1");
  static_assert(
      !kSizes || HasDiscretise<Problem>::value,
      "RtiSolver<Problem>: Problem must have `Vec<kNx> Discretise(const Vec<kNx>& x, const "
      "Vec<kNu>& u, const Params& p, double dt, int steps, Mat<kNx, kNx>* A, Mat<kNx, "
      "kNu>* B) const` (the interval map and, when A and B are not null, its Jacobians)");
  static_assert(
      !kSizes || HasStageResidual<Problem>::value,
      "RtiSolver<Problem>: Problem must have `void StageResidual(const Vec<kNx>& x, const "
      "Vec<kNu>& u, const Params& p, Vec<kNy>* y, Mat<kNy, kNx>* yx, Mat<kNy, kNu>* yu) "
      "const`");
  static_assert(!kSizes || HasTerminalResidual<Problem>::value,
                "RtiSolver<Problem>: Problem must have `void TerminalResidual(const Vec<kNx>& x, "
                "const Params& p, Vec<kNyN>* y, Mat<kNyN, kNx>* yx) const`");
};

template <class P>
constexpr int ParamsSize() {
  if constexpr (std::is_base_of_v<Eigen::EigenBase<P>, P>) {
    return static_cast<int>(P::SizeAtCompileTime);
  } else {
    return 0;
  }
}

/// Parameters with every entry zero for Eigen types, value-initialised otherwise.
template <class P>
P ZeroParams() {
  if constexpr (std::is_base_of_v<Eigen::EigenBase<P>, P>) {
    return P::Zero();
  } else {
    return P{};
  }
}
}  // namespace detail

}  // namespace fnmpc::rti

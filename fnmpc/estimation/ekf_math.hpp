// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Cholesky>
#include <array>
#include <cmath>

#include "fnmpc/core/eigen_abi.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/estimation/ekf_types.hpp"

/// Small numerical helpers of the estimators: chi-square quantiles for the gates, the
/// partial derivatives of the ZYX rotation, and the Joseph-form Kalman update.
namespace fnmpc::estimation {

/// Survival function P[X > x] of a chi-square variable with `dof` degrees of freedom
/// (closed form for integer dof; accurate for dof <= 200, Wilson-Hilferty beyond).
double Chi2Survival(double x, int dof);

/// Quantile x with P[X <= x] = p of a chi-square variable with `dof` degrees of freedom.
/// Throws std::invalid_argument unless 0 < p < 1 and dof >= 1 (setup-time use).
double Chi2Quantile(double p, int dof);

/// R = Rz(psi) Ry(theta) Rx(phi) and its partial derivatives dR[i] = dR / d euler[i],
/// euler = (phi, theta, psi) [rad].
void RotationZyxPartials(const Vec3& euler, Mat3* R, std::array<Mat3, 3>* dR);

/// Makes P exactly symmetric: P = (P + P') / 2 (in place, each pair once; the diagonal,
/// (a + a) / 2 = a, is left as it is).
template <int N>
void Symmetrize(Mat<N, N>* P) {
  for (int j = 1; j < N; ++j) {
    for (int i = 0; i < j; ++i) {
      const double m = 0.5 * ((*P)(i, j) + (*P)(j, i));
      (*P)(i, j) = m;
      (*P)(j, i) = m;
    }
  }
}

/// Guard against forward time jumps of event stamps. An event more than `max_jump` past
/// the newest one is rejected; `reset_count` consecutive such events within `max_jump` of
/// each other mean that the clock really moved on, and the filter should re-anchor.
class TimeJumpGuard {
 public:
  enum class Verdict { kAccept, kReject, kReanchor };

  /// Classifies an event stamped t against the newest event's stamp (NaN: no reference).
  Verdict Check(double t, double newest, double max_jump, int reset_count) {
    if (!std::isfinite(newest) || !(t > newest + max_jump)) {
      count_ = 0;
      return Verdict::kAccept;
    }
    count_ = count_ > 0 && std::abs(t - last_) <= max_jump ? count_ + 1 : 1;
    last_ = t;
    if (count_ < reset_count) return Verdict::kReject;
    count_ = 0;
    return Verdict::kReanchor;
  }
  /// Forgets the jumps seen so far.
  void Reset() { count_ = 0; }

 private:
  int count_ = 0;
  double last_ = kNaN;
};

/// Result of one Kalman update.
struct UpdateResult {
  EkfStatus status = EkfStatus::kAccepted;  ///< kAccepted, kRejectedGated or kNumericalError
  double nis = kNaN;                        ///< normalised innovation squared y' S^-1 y [-]
  double log_det_s = kNaN;                  ///< log det S (S = H P H' + R), for likelihoods
};

/// Joseph-form EKF update x += K y, P = (I-KH) P (I-KH)' + K R K' with innovation y
/// (dim M), Jacobian H (M x N) and noise R (M x M). Rejects (state untouched) when the NIS
/// exceeds `gate` (pass kInf to disable) or when S is not positive definite. Fixed-size:
/// no heap allocation.
template <int N, int M>
UpdateResult KalmanUpdate(const Vec<M>& y, const Mat<M, N>& H, const Mat<M, M>& R, double gate,
                          Vec<N>* x, Mat<N, N>* P) {
  UpdateResult r;
  const Mat<M, N> HP = H * (*P);
  Mat<M, M> S = HP * H.transpose() + R;
  Symmetrize<M>(&S);
  const Eigen::LLT<Mat<M, M>> llt(S);
  if (llt.info() != Eigen::Success || !y.allFinite()) {
    r.status = EkfStatus::kNumericalError;
    return r;
  }
  r.nis = y.dot(llt.solve(y));
  r.log_det_s = 2.0 * llt.matrixLLT().diagonal().array().log().sum();
  if (!std::isfinite(r.nis)) {
    r.status = EkfStatus::kNumericalError;
    return r;
  }
  if (r.nis > gate) {
    r.status = EkfStatus::kRejectedGated;
    return r;
  }
  const Mat<N, M> K = llt.solve(HP).transpose();
  const Vec<N> x_new = *x + K * y;
  // The Joseph form through the rank-M factors: (I - K H) P = P - K (H P) and
  // X (I - K H)' = X - (X H') K', no N x N x N product.
  const Mat<N, N> X = *P - K * HP;
  Mat<N, N> P_new = X - (X * H.transpose()) * K.transpose() + K * R * K.transpose();
  Symmetrize<N>(&P_new);
  if (!x_new.allFinite() || !P_new.allFinite() || (P_new.diagonal().array() <= 0.0).any()) {
    r.status = EkfStatus::kNumericalError;
    return r;
  }
  *x = x_new;
  *P = P_new;
  return r;
}

}  // namespace fnmpc::estimation

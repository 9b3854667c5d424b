// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/model/follower_model.hpp"
#include "fnmpc/model/quadrotor_model.hpp"
#include "fnmpc/model/rk4.hpp"

/// Nonlinear least-squares optimal control problems (stage and terminal residuals) on
/// top of the models. The cost of stage k is 0.5 |y(x_k, u_k, p_k) - yref_k|^2_W and the
/// terminal cost 0.5 |yN(x_N, p_N) - yrefN|^2_WN; the RtiSolver owns W, references,
/// parameters and bounds. Each problem meets the solver's contract (docs/rti.md) and states
/// its residual layout; p_k are the stage parameters (online data), here p[0] is always the
/// yaw reference psi_ref [rad] that the quadrotor models take.
///
/// Residual Jacobians (yx, yu, ynx; nullptr = not wanted) are written only at their
/// structural nonzeros, the same entries on every call: the caller zeroes them once. The
/// solver finds the sparsity of the Gauss-Newton blocks from the entries written.
namespace fnmpc::ocp {

/// Frame in which a follower's desired relative positions d_j are expressed: the MPC
/// inertial frame {m} (world-aligned) or the yaw-rotated control frame {c} of the
/// reference work (roll- and pitch-free, rotated by the follower's own yaw).
enum class TargetFrame { kInertial, kControl };

/// Problem L: single-vehicle tracking. y = [p (3), v (3), phi, theta, T - m g, phi_ref,
/// theta_ref] (11), yN = [p, v, phi, theta] (8), p = [psi_ref].
struct LeaderProblem {
  using Model = model::QuadrotorModel;
  static constexpr int kNx = 9, kNu = 3, kNy = 11, kNyN = 8, kNp = 1;
  model::AttitudeModelParams params;
  /// Per-stage parameters of the solver contract (docs/rti.md); p[0] = psi_ref [rad].
  using Params = Vec<kNp>;
  /// The model's RK4 interval map with its sensitivities (docs/rti.md, the contract).
  Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, const Params& p, double dt, int steps,
                      Mat<kNx, kNx>* A, Mat<kNx, kNu>* B) const {
    return model::Discretise<Model>(x, u, p[0], params, dt, steps, A, B);
  }

  void StageResidual(const Vec<kNx>& x, const Vec<kNu>& u, const Vec<kNp>& /*p*/, Vec<kNy>* y,
                     Mat<kNy, kNx>* yx, Mat<kNy, kNu>* yu) const {
    y->head<8>() = x.head<8>();
    (*y)[8] = u[0] - params.mass * kGravity;
    y->tail<2>() = u.tail<2>();
    if (yx != nullptr) {
      yx->topLeftCorner<8, 8>().diagonal().setOnes();
      yu->bottomRows<3>().diagonal().setOnes();
    }
  }
  void TerminalResidual(const Vec<kNx>& x, const Vec<kNp>& /*p*/, Vec<kNyN>* y,
                        Mat<kNyN, kNx>* yx) const {
    *y = x.head<8>();
    if (yx != nullptr) yx->leftCols<8>().diagonal().setOnes();
  }
};

/// Shared part of the follower residuals: the three relative-position rows of a relative
/// position r, Rz(psi)^T r in target frame {c} or r in {m}, written at `row` of y; with yx,
/// also sign * d rows/d r at (row, r_col) and d rows/d psi at (row, psi_col), where r =
/// sign * (state at r_col) + const. In {m} only the diagonal of d rows/d r is written: the
/// structural nonzeros, so the solver's Gauss-Newton blocks skip the zero couplings between
/// the axes and with the yaw.
struct RelativeRows {
  template <class Yv, class Jx>
  static void Write(TargetFrame frame, const Vec3& r, double psi, double sign, int row, int r_col,
                    int psi_col, Yv* y, Jx* yx) {
    if (frame == TargetFrame::kInertial) {
      y->template segment<3>(row) = r;
      if (yx != nullptr) yx->template block<3, 3>(row, r_col).diagonal().setConstant(sign);
      return;
    }
    const double c = std::cos(psi), s = std::sin(psi);
    y->template segment<3>(row) = Vec3(c * r.x() + s * r.y(), -s * r.x() + c * r.y(), r.z());
    if (yx == nullptr) return;
    Mat3 dy_dr;
    dy_dr << c, s, 0, -s, c, 0, 0, 0, 1;
    yx->template block<3, 3>(row, r_col) = sign * dy_dr;
    yx->template block<3, 1>(row, psi_col) =
        Vec3(-s * r.x() + c * r.y(), -c * r.x() - s * r.y(), 0.0);
  }
};

/// Problems F2, F6 (the reference formulation): follower with `Neighbours` neighbours in
/// its state. y = [rel_1..rel_n (3n), v_1 - v .. v_n - v (3n), phi, theta, T - m g,
/// phi_ref, theta_ref] with rel_j = dx_j ({m}) or Rz(psi)^T dx_j ({c});
/// yN = first 6n + 2 entries of y; p = [psi_ref].
template <int Neighbours>
struct FollowerProblem {
  using Model = model::FollowerModel<Neighbours>;
  static constexpr int kN = Neighbours;
  static constexpr int kNx = Model::kNx, kNu = 3, kNy = 6 * kN + 5, kNyN = 6 * kN + 2, kNp = 1;
  model::AttitudeModelParams params;
  TargetFrame frame = TargetFrame::kInertial;
  /// Per-stage parameters of the solver contract (docs/rti.md); p[0] = psi_ref [rad].
  using Params = Vec<kNp>;
  /// The model's RK4 interval map with its sensitivities (docs/rti.md, the contract).
  Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, const Params& p, double dt, int steps,
                      Mat<kNx, kNx>* A, Mat<kNx, kNu>* B) const {
    return model::Discretise<Model>(x, u, p[0], params, dt, steps, A, B);
  }

  template <int Ny>
  void Rows(const Vec<kNx>& x, Vec<Ny>* y, Mat<Ny, kNx>* yx) const {
    const double psi = x[Model::kPsi];
    for (int j = 0; j < kN; ++j) {
      const int o = Model::Neighbour(j);
      RelativeRows::Write(frame, x.template segment<3>(o), psi, 1.0, 3 * j, o, Model::kPsi, y, yx);
      y->template segment<3>(3 * kN + 3 * j) =
          x.template segment<3>(o + model::NeighbourIndex::kVel) -
          x.template segment<3>(Model::kVel);
      if (yx != nullptr) {
        yx->template block<3, 3>(3 * kN + 3 * j, o + model::NeighbourIndex::kVel)
            .diagonal()
            .setOnes();
        yx->template block<3, 3>(3 * kN + 3 * j, Model::kVel).diagonal().setConstant(-1.0);
      }
    }
    (*y)[6 * kN] = x[Model::kPhi];
    (*y)[6 * kN + 1] = x[Model::kTheta];
    if (yx != nullptr) {
      (*yx)(6 * kN, Model::kPhi) = 1.0;
      (*yx)(6 * kN + 1, Model::kTheta) = 1.0;
    }
  }

  void StageResidual(const Vec<kNx>& x, const Vec<kNu>& u, const Vec<kNp>& /*p*/, Vec<kNy>* y,
                     Mat<kNy, kNx>* yx, Mat<kNy, kNu>* yu) const {
    if (yu != nullptr) yu->template bottomRows<3>().diagonal().setOnes();
    Rows<kNy>(x, y, yx);
    (*y)[6 * kN + 2] = u[0] - params.mass * kGravity;
    y->template tail<2>() = u.template tail<2>();
  }
  void TerminalResidual(const Vec<kNx>& x, const Vec<kNp>& /*p*/, Vec<kNyN>* y,
                        Mat<kNyN, kNx>* yx) const {
    Rows<kNyN>(x, y, yx);
  }
};

/// Reduced follower formulation: the neighbours' constant-velocity predictions become
/// time-varying stage parameters, so the state is own displacement s (since the current
/// time), velocity and attitude, nx = 9, whatever the number of neighbours; the dynamics
/// are those of QuadrotorModel with s in place of p. With c_j(t) = dx_j(0) + t v_j the
/// predicted neighbour offset, the relative position is dx_j = c_j - s, so the residuals
/// equal FollowerProblem's. p = [psi_ref, then per neighbour c_j (3), v_j (3)].
template <int Neighbours>
struct ReducedFollowerProblem {
  using Model = model::QuadrotorModel;
  static constexpr int kN = Neighbours;
  static constexpr int kNx = 9, kNu = 3, kNy = 6 * kN + 5, kNyN = 6 * kN + 2, kNp = 1 + 6 * kN;
  model::AttitudeModelParams params;
  TargetFrame frame = TargetFrame::kInertial;
  /// Per-stage parameters of the solver contract (docs/rti.md); p[0] = psi_ref [rad].
  using Params = Vec<kNp>;
  /// The model's RK4 interval map with its sensitivities (docs/rti.md, the contract).
  Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, const Params& p, double dt, int steps,
                      Mat<kNx, kNx>* A, Mat<kNx, kNu>* B) const {
    return model::Discretise<Model>(x, u, p[0], params, dt, steps, A, B);
  }

  /// Offsets of neighbour j's predicted relative position and velocity in p.
  static constexpr int ParamRelPos(int j) { return 1 + 6 * j; }
  static constexpr int ParamVel(int j) { return 4 + 6 * j; }

  template <int Ny>
  void Rows(const Vec<kNx>& x, const Vec<kNp>& p, Vec<Ny>* y, Mat<Ny, kNx>* yx) const {
    const double psi = x[Model::kPsi];
    for (int j = 0; j < kN; ++j) {
      const Vec3 r = p.template segment<3>(ParamRelPos(j)) - x.template segment<3>(Model::kPos);
      RelativeRows::Write(frame, r, psi, -1.0, 3 * j, Model::kPos, Model::kPsi, y, yx);
      y->template segment<3>(3 * kN + 3 * j) =
          p.template segment<3>(ParamVel(j)) - x.template segment<3>(Model::kVel);
      if (yx != nullptr) {
        yx->template block<3, 3>(3 * kN + 3 * j, Model::kVel).diagonal().setConstant(-1.0);
      }
    }
    (*y)[6 * kN] = x[Model::kPhi];
    (*y)[6 * kN + 1] = x[Model::kTheta];
    if (yx != nullptr) {
      (*yx)(6 * kN, Model::kPhi) = 1.0;
      (*yx)(6 * kN + 1, Model::kTheta) = 1.0;
    }
  }

  void StageResidual(const Vec<kNx>& x, const Vec<kNu>& u, const Vec<kNp>& p, Vec<kNy>* y,
                     Mat<kNy, kNx>* yx, Mat<kNy, kNu>* yu) const {
    if (yu != nullptr) yu->template bottomRows<3>().diagonal().setOnes();
    Rows<kNy>(x, p, y, yx);
    (*y)[6 * kN + 2] = u[0] - params.mass * kGravity;
    y->template tail<2>() = u.template tail<2>();
  }
  void TerminalResidual(const Vec<kNx>& x, const Vec<kNp>& p, Vec<kNyN>* y,
                        Mat<kNyN, kNx>* yx) const {
    Rows<kNyN>(x, p, y, yx);
  }
};

}  // namespace fnmpc::ocp

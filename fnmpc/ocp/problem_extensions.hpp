// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>

#include "fnmpc/core/types.hpp"
#include "fnmpc/model/input_memory_model.hpp"
#include "fnmpc/model/rk4.hpp"

/// Extensions of a least-squares problem (fnmpc/ocp/problems.hpp contract) for the
/// controllers: collision avoidance, input-rate costs and an external acceleration. Each wraps any
/// problem, keeps its residuals and parameters first and appends its own, so the benchmark problems
/// stay as the spec defines them. The wrapped problem's Jacobians are passed through temporaries
/// that start as the caller's blocks, so only the entries the wrapped problem writes change (the
/// solver's sparsity detection relies on it).
namespace fnmpc::ocp {

/// Soft collision avoidance against `Slots` obstacles: one residual row per obstacle o,
///   e_o = min(0, n_o . (c_o - p) - r_min),
/// a one-sided quadratic penalty on entering the half-space within r_min of obstacle o along
/// the unit normal n_o (a separating plane through the linearisation, fixed over the horizon
/// so that predicted paths that cross do not flip the gradient; the caller re-linearises it
/// at every sampling time from the current relative position). Gauss-Newton linearises it at
/// every iteration: a soft constraint inside the OCP. p is the position block of the wrapped
/// problem's state (Model::kPos, in the frame of its parameters); c_o and n_o are stage
/// parameters appended after the wrapped problem's; an unused slot is far away. Appended to
/// the stage and terminal residuals.
template <class P, int Slots>
struct WithObstacles {
  using Model = typename P::Model;
  static constexpr int kSlots = Slots;
  static constexpr int kNx = P::kNx, kNu = P::kNu, kNy = P::kNy + Slots, kNyN = P::kNyN + Slots,
                       kNp = P::kNp + 6 * Slots;
  static constexpr int kPos = Model::kPos;
  P base;
  model::AttitudeModelParams params;
  double radius = 0.45;  ///< r_min [m]

  explicit WithObstacles(const P& p = P{}, double r_min = 0.45)
      : base(p), params(p.params), radius(r_min) {}

  /// Per-stage parameters of the solver contract (docs/rti.md); p[0] = psi_ref [rad].
  using Params = Vec<kNp>;
  /// The model's RK4 interval map with its sensitivities (docs/rti.md, the contract).
  Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, const Params& p, double dt, int steps,
                      Mat<kNx, kNx>* A, Mat<kNx, kNu>* B) const {
    return model::Discretise<Model>(x, u, p[0], params, dt, steps, A, B);
  }

  /// Offsets of obstacle o's position c_o and of its unit normal n_o in p.
  static constexpr int ParamObstacle(int o) { return P::kNp + 6 * o; }
  static constexpr int ParamNormal(int o) { return P::kNp + 6 * o + 3; }
  /// Writes an unused slot into p: far outside any radius along its normal.
  template <class Pv>
  static void SetUnused(int o, Pv* p) {
    p->template segment<3>(ParamObstacle(o)) = Vec3(0.0, 0.0, 1e4);
    p->template segment<3>(ParamNormal(o)) = Vec3(0.0, 0.0, 1.0);
  }

  void StageResidual(const Vec<kNx>& x, const Vec<kNu>& u, const Vec<kNp>& p, Vec<kNy>* y,
                     Mat<kNy, kNx>* yx, Mat<kNy, kNu>* yu) const {
    Vec<P::kNy> yb;
    if (yx == nullptr) {
      base.StageResidual(x, u, p.template head<P::kNp>(), &yb, nullptr, nullptr);
    } else {
      Mat<P::kNy, kNx> bx = yx->template topRows<P::kNy>();
      Mat<P::kNy, kNu> bu = yu->template topRows<P::kNy>();
      base.StageResidual(x, u, p.template head<P::kNp>(), &yb, &bx, &bu);
      yx->template topRows<P::kNy>() = bx;
      yu->template topRows<P::kNy>() = bu;
    }
    y->template head<P::kNy>() = yb;
    Rows(x, p, P::kNy, y, yx);
  }

  void TerminalResidual(const Vec<kNx>& x, const Vec<kNp>& p, Vec<kNyN>* y,
                        Mat<kNyN, kNx>* yx) const {
    Vec<P::kNyN> yb;
    if (yx == nullptr) {
      base.TerminalResidual(x, p.template head<P::kNp>(), &yb, nullptr);
    } else {
      Mat<P::kNyN, kNx> bx = yx->template topRows<P::kNyN>();
      base.TerminalResidual(x, p.template head<P::kNp>(), &yb, &bx);
      yx->template topRows<P::kNyN>() = bx;
    }
    y->template head<P::kNyN>() = yb;
    Rows(x, p, P::kNyN, y, yx);
  }

 private:
  // Writes the three position entries of every row on every call (zero when inactive): the
  // same structural nonzeros each time.
  template <class Yv, class Jx>
  void Rows(const Vec<kNx>& x, const Vec<kNp>& p, int row0, Yv* y, Jx* yx) const {
    for (int o = 0; o < Slots; ++o) {
      const Vec3 n = p.template segment<3>(ParamNormal(o));
      const double gap =
          n.dot(p.template segment<3>(ParamObstacle(o)) - x.template segment<3>(kPos));
      const bool active = gap < radius;
      (*y)[row0 + o] = active ? gap - radius : 0.0;
      if (yx == nullptr) continue;
      const Vec3 g = active ? Vec3(-n) : Vec3(Vec3::Zero());  // d gap / d p = -n
      yx->template block<1, 3>(row0 + o, kPos) = g.transpose();
    }
  }
};

/// Input-rate cost of the reference work: the state carries the previous input
/// (model::InputMemoryModel) and the stage residual gains u_k - u_prev_k, the change between
/// consecutive stages and, at k = 0, from the command last applied (set in x_0). The
/// terminal residual is the wrapped problem's.
template <class P>
struct WithInputRate {
  using Model = model::InputMemoryModel<typename P::Model>;
  static constexpr int kNxBase = P::kNx, kNx = Model::kNx, kNu = P::kNu, kNy = P::kNy + kNu,
                       kNyN = P::kNyN, kNp = P::kNp;
  static constexpr int kPrevInput = Model::kPrevInput;
  P base;
  model::AttitudeModelParams params;

  explicit WithInputRate(const P& p = P{}) : base(p), params(p.params) {}

  /// Per-stage parameters of the solver contract (docs/rti.md); p[0] = psi_ref [rad].
  using Params = Vec<kNp>;
  /// The model's RK4 interval map with its sensitivities (docs/rti.md, the contract).
  Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, const Params& p, double dt, int steps,
                      Mat<kNx, kNx>* A, Mat<kNx, kNu>* B) const {
    return model::Discretise<Model>(x, u, p[0], params, dt, steps, A, B);
  }

  void StageResidual(const Vec<kNx>& x, const Vec<kNu>& u, const Vec<kNp>& p, Vec<kNy>* y,
                     Mat<kNy, kNx>* yx, Mat<kNy, kNu>* yu) const {
    Vec<P::kNy> yb;
    const Vec<kNxBase> xb = x.template head<kNxBase>();
    if (yx == nullptr) {
      base.StageResidual(xb, u, p, &yb, nullptr, nullptr);
    } else {
      Mat<P::kNy, kNxBase> bx = yx->template topLeftCorner<P::kNy, kNxBase>();
      Mat<P::kNy, kNu> bu = yu->template topRows<P::kNy>();
      base.StageResidual(xb, u, p, &yb, &bx, &bu);
      yx->template topLeftCorner<P::kNy, kNxBase>() = bx;
      yu->template topRows<P::kNy>() = bu;
      yx->template block<kNu, kNu>(P::kNy, kPrevInput).diagonal().setConstant(-1.0);
      yu->template bottomRows<kNu>().diagonal().setOnes();
    }
    y->template head<P::kNy>() = yb;
    y->template tail<kNu>() = u - x.template tail<kNu>();
  }

  void TerminalResidual(const Vec<kNx>& x, const Vec<kNp>& p, Vec<kNyN>* y,
                        Mat<kNyN, kNx>* yx) const {
    Vec<P::kNyN> yb;
    const Vec<kNxBase> xb = x.template head<kNxBase>();
    if (yx == nullptr) {
      base.TerminalResidual(xb, p, &yb, nullptr);
    } else {
      Mat<P::kNyN, kNxBase> bx = yx->template leftCols<kNxBase>();
      base.TerminalResidual(xb, p, &yb, &bx);
      yx->template leftCols<kNxBase>() = bx;
    }
    *y = yb;
  }
};

/// Base of the extensions that change only the dynamics of the wrapped problem P
/// (WithAcceleration, WithWake in wake_extension.hpp): the sizes are P's, `Extra` parameters
/// are appended after P's, and the residuals are P's on its own leading parameters. The
/// extension adds its Discretise (and Model when its transition matrix has other couplings).
template <class P, int Extra>
struct DynamicsExtension {
  static constexpr int kNx = P::kNx, kNu = P::kNu, kNy = P::kNy, kNyN = P::kNyN,
                       kNp = P::kNp + Extra;
  P base;

  explicit DynamicsExtension(const P& p) : base(p) {}

  /// Per-stage parameters of the solver contract (docs/rti.md): the wrapped problem's, then
  /// the extension's.
  using Params = Vec<kNp>;

  void StageResidual(const Vec<kNx>& x, const Vec<kNu>& u, const Vec<kNp>& p, Vec<kNy>* y,
                     Mat<kNy, kNx>* yx, Mat<kNy, kNu>* yu) const {
    base.StageResidual(x, u, p.template head<P::kNp>(), y, yx, yu);
  }

  void TerminalResidual(const Vec<kNx>& x, const Vec<kNp>& p, Vec<kNyN>* y,
                        Mat<kNyN, kNx>* yx) const {
    base.TerminalResidual(x, p.template head<P::kNp>(), y, yx);
  }
};

/// External acceleration a (the disturbance observer's estimate, offset-free NMPC) as a stage
/// parameter, appended after the wrapped problem's: the dynamics become
///   p' = v,  v' = f_v(angles, u) + a
/// for the wrapped problem's position block at `Pos` and velocity block at `Vel` (any model
/// whose v' does not depend on p or v, as the quadrotor models: the other rows are untouched).
/// Held constant over each interval, a adds exactly a dt to v and a dt^2 / 2 to p; RK4 is
/// exact for that part too (its stages are linear in a constant forcing of a double
/// integrator), so the interval map is the wrapped one plus these terms and its
/// sensitivities A, B are the wrapped ones. With a = 0 the map is the wrapped problem's, to
/// the bit. Residuals are the wrapped problem's (DynamicsExtension).
template <class P, int Pos = 0, int Vel = 3>
struct WithAcceleration : DynamicsExtension<P, 3> {
  using Model = typename P::Model;
  using Ext = DynamicsExtension<P, 3>;
  using Ext::kNp;
  using Ext::kNu;
  using Ext::kNx;
  using typename Ext::Params;
  static_assert(Pos + 3 <= kNx && Vel + 3 <= kNx, "position and velocity blocks in the state");
  /// Offset of the acceleration a [m/s^2] in the stage parameters.
  static constexpr int kParamAcceleration = P::kNp;

  explicit WithAcceleration(const P& p = P{}) : Ext(p) {}

  Vec<kNx> Discretise(const Vec<kNx>& x, const Vec<kNu>& u, const Params& p, double dt, int steps,
                      Mat<kNx, kNx>* A, Mat<kNx, kNu>* B) const {
    const typename P::Params pb = p.template head<P::kNp>();
    Vec<kNx> next = this->base.Discretise(x, u, pb, dt, steps, A, B);
    const Vec3 a = p.template segment<3>(kParamAcceleration);
    next.template segment<3>(Pos) += (0.5 * dt * dt) * a;
    next.template segment<3>(Vel) += dt * a;
    return next;
  }
};

}  // namespace fnmpc::ocp

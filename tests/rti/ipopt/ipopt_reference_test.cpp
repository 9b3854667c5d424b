// SPDX-License-Identifier: BSD-3-Clause
// The RtiSolver's converged first call (Algorithm 1 at t = 0, KKT < 1e-6) against IPOPT,
// an interior-point solver nobody here wrote, on the same discretised NLP: multiple
// shooting over N = 15 intervals, x_{k+1} = RK4(x_k, u_k) (Ts = 0.05 s, 2 steps), the
// spec's least-squares costs, input bounds and HARD state bounds. IPOPT gets the exact
// cost Hessian and the dynamics' second derivatives by central differences of the exact
// RK4 sensitivities, and solves to tol 1e-10. The benchmark problems L and F2
// (docs/benchmark-spec.md) are checked with and without active bounds.
#include <gtest/gtest.h>
#include <IpIpoptApplication.hpp>
#include <IpSolveStatistics.hpp>
#include <IpTNLP.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "bench/ocp_spec/benchmark_ocps.hpp"
#include "fnmpc/core/types.hpp"
#include "fnmpc/model/follower_model.hpp"
#include "fnmpc/model/quadrotor_model.hpp"
#include "fnmpc/model/rk4.hpp"
#include "fnmpc/rti/rti_solver.hpp"

namespace fnmpc::bench {
namespace {

/// Infinite bound for IPOPT (anything beyond +-1e19 is treated as absent).
constexpr double kIpoptInf = 1e20;

/// A multiple-shooting OCP with residuals affine in (x, u), written out from the spec
/// independently of fnmpc/ocp: stage cost 0.5 |cx x_k + cu u_k - target_k|^2_W, terminal
/// cost 0.5 |cxn x_N - target_n|^2_WN, x_0 fixed, bounds on u_k (k = 0..N-1) and on the
/// components `bounded` of x_k (k = 1..N).
template <class Model>
struct ShootingOcp {
  static constexpr int kNx = Model::kNx, kNu = Model::kNu;
  int horizon = 15;
  double sample_time = 0.05;  ///< [s]
  int integrator_steps = 2;
  model::AttitudeModelParams params;
  double psi_ref = 0.0;  ///< [rad] online data of every node
  Vec<kNx> x0 = Vec<kNx>::Zero();
  MatX cx, cu;                     ///< stage residual matrices (ny x nx, ny x nu)
  VecX w;                          ///< stage weights (ny)
  std::vector<VecX> target;        ///< per stage (ny): reference plus residual constants
  MatX cxn;                        ///< terminal residual matrix (nyN x nx)
  VecX wn, target_n;               ///< terminal weights and target (nyN)
  std::vector<int> bounded;        ///< bounded state components
  std::vector<Vec<kNx>> lbx, ubx;  ///< nodes 0..N (node 0 unused)
  std::vector<Vec<kNu>> lbu, ubu;  ///< stages 0..N-1
  std::vector<Vec<kNx>> x_guess;   ///< nodes 0..N
  std::vector<Vec<kNu>> u_guess;   ///< stages 0..N-1
};

/// IPOPT's solution of a ShootingOcp.
template <class Model>
struct ShootingSolution {
  Ipopt::ApplicationReturnStatus status = Ipopt::Internal_Error;
  int iterations = 0;
  double objective = kNaN;
  std::vector<Vec<Model::kNx>> x;
  std::vector<Vec<Model::kNu>> u;
};

/// ShootingOcp as an IPOPT TNLP. Variables z = [x_0, u_0, x_1, u_1, ..., x_{N-1},
/// u_{N-1}, x_N]; constraints g_k = RK4(x_k, u_k) - x_{k+1} = 0 (k = 0..N-1).
template <class Model>
class ShootingTnlp : public Ipopt::TNLP {
 public:
  static constexpr int kNx = Model::kNx, kNu = Model::kNu, kNz = kNx + kNu;
  using Index = Ipopt::Index;
  using Number = Ipopt::Number;

  ShootingTnlp(const ShootingOcp<Model>& ocp, ShootingSolution<Model>* out)
      : ocp_(ocp), out_(out), n_(ocp.horizon) {
    const MatX c = Concat(ocp_.cx, ocp_.cu);
    stage_hessian_ = c.transpose() * ocp_.w.asDiagonal() * c;
    terminal_hessian_ = ocp_.cxn.transpose() * ocp_.wn.asDiagonal() * ocp_.cxn;
  }

  bool get_nlp_info(Index& n, Index& m, Index& nnz_jac_g, Index& nnz_h_lag,
                    IndexStyleEnum& index_style) override {
    n = NumVariables();
    m = n_ * kNx;
    nnz_jac_g = n_ * (kNx * kNz + kNx);
    nnz_h_lag = n_ * kNz * (kNz + 1) / 2 + kNx * (kNx + 1) / 2;
    index_style = C_STYLE;
    return true;
  }

  bool get_bounds_info(Index n, Number* x_l, Number* x_u, Index m, Number* g_l,
                       Number* g_u) override {
    std::fill(x_l, x_l + n, -kIpoptInf);
    std::fill(x_u, x_u + n, kIpoptInf);
    for (int i = 0; i < kNx; ++i) x_l[i] = x_u[i] = ocp_.x0[i];  // x_0 fixed
    for (int k = 0; k < n_; ++k) {
      for (int i = 0; i < kNu; ++i) {
        x_l[U(k) + i] = Finite(ocp_.lbu[k][i]);
        x_u[U(k) + i] = Finite(ocp_.ubu[k][i]);
      }
    }
    for (int k = 1; k <= n_; ++k) {
      for (int i : ocp_.bounded) {
        x_l[X(k) + i] = Finite(ocp_.lbx[k][i]);
        x_u[X(k) + i] = Finite(ocp_.ubx[k][i]);
      }
    }
    std::fill(g_l, g_l + m, 0.0);
    std::fill(g_u, g_u + m, 0.0);
    return true;
  }

  bool get_starting_point(Index /*n*/, bool init_x, Number* z, bool init_z, Number* /*z_L*/,
                          Number* /*z_U*/, Index /*m*/, bool init_lambda,
                          Number* /*lambda*/) override {
    if (!init_x || init_z || init_lambda) return false;
    for (int k = 0; k <= n_; ++k) XMap(z, k) = ocp_.x_guess[k];
    for (int k = 0; k < n_; ++k) UMap(z, k) = ocp_.u_guess[k];
    return true;
  }

  bool eval_f(Index /*n*/, const Number* z, bool /*new_x*/, Number& obj_value) override {
    double f = 0.0;
    for (int k = 0; k < n_; ++k) {
      const VecX r = StageResidual(z, k);
      f += 0.5 * r.dot(ocp_.w.cwiseProduct(r));
    }
    const VecX rn = TerminalResidual(z);
    obj_value = f + 0.5 * rn.dot(ocp_.wn.cwiseProduct(rn));
    return true;
  }

  bool eval_grad_f(Index n, const Number* z, bool /*new_x*/, Number* grad_f) override {
    std::fill(grad_f, grad_f + n, 0.0);
    for (int k = 0; k < n_; ++k) {
      const VecX wr = ocp_.w.cwiseProduct(StageResidual(z, k));
      Eigen::Map<Vec<kNx>>(grad_f + X(k)) = ocp_.cx.transpose() * wr;
      Eigen::Map<Vec<kNu>>(grad_f + U(k)) = ocp_.cu.transpose() * wr;
    }
    Eigen::Map<Vec<kNx>>(grad_f + X(n_)) =
        ocp_.cxn.transpose() * ocp_.wn.cwiseProduct(TerminalResidual(z));
    return true;
  }

  bool eval_g(Index /*n*/, const Number* z, bool /*new_x*/, Index /*m*/, Number* g) override {
    for (int k = 0; k < n_; ++k) {
      Eigen::Map<Vec<kNx>>(g + k * kNx) = Discrete(XMap(z, k), UMap(z, k)) - XMap(z, k + 1);
    }
    return true;
  }

  bool eval_jac_g(Index /*n*/, const Number* z, bool /*new_x*/, Index /*m*/, Index /*nele*/,
                  Index* i_row, Index* j_col, Number* values) override {
    int e = 0;
    if (values == nullptr) {
      for (int k = 0; k < n_; ++k) {
        for (int i = 0; i < kNx; ++i) {
          for (int j = 0; j < kNz; ++j) {
            i_row[e] = k * kNx + i;
            j_col[e++] = X(k) + j;
          }
          i_row[e] = k * kNx + i;
          j_col[e++] = X(k + 1) + i;
        }
      }
      return true;
    }
    Mat<kNx, kNx> a;
    Mat<kNx, kNu> b;
    for (int k = 0; k < n_; ++k) {
      Discrete(XMap(z, k), UMap(z, k), &a, &b);
      for (int i = 0; i < kNx; ++i) {
        for (int j = 0; j < kNx; ++j) values[e++] = a(i, j);
        for (int j = 0; j < kNu; ++j) values[e++] = b(i, j);
        values[e++] = -1.0;
      }
    }
    return true;
  }

  /// Hessian of the Lagrangian: the exact (constant) cost Hessian plus the dynamics'
  /// second derivatives, central differences of w -> [A(w) B(w)]^T lambda_k, which are
  /// exact first derivatives of the RK4 map (errors ~1e-10 only slow IPOPT down; they
  /// cannot move its solution, which is fixed by the exact gradient and Jacobian).
  bool eval_h(Index /*n*/, const Number* z, bool /*new_x*/, Number obj_factor, Index /*m*/,
              const Number* lambda, bool /*new_lambda*/, Index /*nele*/, Index* i_row, Index* j_col,
              Number* values) override {
    int e = 0;
    if (values == nullptr) {
      for (int k = 0; k <= n_; ++k) {
        const int size = k < n_ ? kNz : kNx;
        for (int r = 0; r < size; ++r) {
          for (int c = 0; c <= r; ++c) {
            i_row[e] = X(k) + r;
            j_col[e++] = X(k) + c;
          }
        }
      }
      return true;
    }
    Mat<kNz, kNz> h, hd;
    for (int k = 0; k < n_; ++k) {
      const Eigen::Map<const Vec<kNx>> lam(lambda + k * kNx);
      Vec<kNz> w;
      w << XMap(z, k), UMap(z, k);
      for (int j = 0; j < kNz; ++j) {
        const double step = 1e-6 * (1.0 + std::abs(w[j]));
        Vec<kNz> wp = w, wm = w;
        wp[j] += step;
        wm[j] -= step;
        hd.col(j) = (WeightedJacobian(wp, lam) - WeightedJacobian(wm, lam)) / (2.0 * step);
      }
      h = obj_factor * stage_hessian_ + 0.5 * (hd + hd.transpose());
      for (int r = 0; r < kNz; ++r) {
        for (int c = 0; c <= r; ++c) values[e++] = h(r, c);
      }
    }
    for (int r = 0; r < kNx; ++r) {
      for (int c = 0; c <= r; ++c) values[e++] = obj_factor * terminal_hessian_(r, c);
    }
    return true;
  }

  void finalize_solution(Ipopt::SolverReturn /*status*/, Index /*n*/, const Number* z,
                         const Number* /*z_L*/, const Number* /*z_U*/, Index /*m*/,
                         const Number* /*g*/, const Number* /*lambda*/, Number obj_value,
                         const Ipopt::IpoptData* /*ip_data*/,
                         Ipopt::IpoptCalculatedQuantities* /*ip_cq*/) override {
    out_->x.resize(n_ + 1);
    out_->u.resize(n_);
    for (int k = 0; k <= n_; ++k) out_->x[k] = XMap(z, k);
    for (int k = 0; k < n_; ++k) out_->u[k] = UMap(z, k);
    out_->objective = obj_value;
  }

 private:
  static MatX Concat(const MatX& a, const MatX& b) {
    MatX c(a.rows(), a.cols() + b.cols());
    c << a, b;
    return c;
  }
  static double Finite(double v) { return std::clamp(v, -kIpoptInf, kIpoptInf); }
  [[nodiscard]] int NumVariables() const { return n_ * kNz + kNx; }
  static int X(int k) { return k * kNz; }
  static int U(int k) { return k * kNz + kNx; }
  static Eigen::Map<const Vec<kNx>> XMap(const Number* z, int k) {
    return Eigen::Map<const Vec<kNx>>(z + X(k));
  }
  static Eigen::Map<const Vec<kNu>> UMap(const Number* z, int k) {
    return Eigen::Map<const Vec<kNu>>(z + U(k));
  }
  static Eigen::Map<Vec<kNx>> XMap(Number* z, int k) { return Eigen::Map<Vec<kNx>>(z + X(k)); }
  static Eigen::Map<Vec<kNu>> UMap(Number* z, int k) { return Eigen::Map<Vec<kNu>>(z + U(k)); }

  Vec<kNx> Discrete(const Vec<kNx>& x, const Vec<kNu>& u, Mat<kNx, kNx>* a = nullptr,
                    Mat<kNx, kNu>* b = nullptr) const {
    return model::Rk4<Model>(x, u, ocp_.psi_ref, ocp_.params, ocp_.sample_time,
                             ocp_.integrator_steps, a, b);
  }
  Vec<kNz> WeightedJacobian(const Vec<kNz>& w, const Vec<kNx>& lam) const {
    Mat<kNx, kNx> a;
    Mat<kNx, kNu> b;
    Discrete(w.template head<kNx>(), w.template tail<kNu>(), &a, &b);
    Vec<kNz> out;
    out << a.transpose() * lam, b.transpose() * lam;
    return out;
  }
  VecX StageResidual(const Number* z, int k) const {
    return ocp_.cx * XMap(z, k) + ocp_.cu * UMap(z, k) - ocp_.target[k];
  }
  VecX TerminalResidual(const Number* z) const { return ocp_.cxn * XMap(z, n_) - ocp_.target_n; }

  ShootingOcp<Model> ocp_;
  ShootingSolution<Model>* out_;
  int n_;
  MatX stage_hessian_, terminal_hessian_;
};

/// Solves `ocp` with IPOPT to tol 1e-10 (exact problem: no bound relaxation, no scaling).
template <class Model>
ShootingSolution<Model> SolveWithIpopt(const ShootingOcp<Model>& ocp) {
  ShootingSolution<Model> solution;
  Ipopt::SmartPtr<Ipopt::TNLP> nlp = new ShootingTnlp<Model>(ocp, &solution);
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
  app->Options()->SetStringValue("sb", "yes");
  app->Options()->SetIntegerValue("print_level", 0);
  app->Options()->SetNumericValue("tol", 1e-10);
  app->Options()->SetNumericValue("bound_relax_factor", 0.0);
  app->Options()->SetStringValue("nlp_scaling_method", "none");
  app->Options()->SetStringValue("hessian_approximation", "exact");
  app->Options()->SetIntegerValue("max_iter", 300);
  if (app->Initialize() != Ipopt::Solve_Succeeded) return solution;
  solution.status = app->OptimizeTNLP(nlp);
  if (IsValid(app->Statistics())) solution.iterations = app->Statistics()->IterationCount();
  return solution;
}

/// Copies the solver's bounds, layout, horizon, settings and initial guess into `ocp`.
template <class Model, class Solver>
void CopySolverData(const Solver& solver, ShootingOcp<Model>* ocp) {
  const int n = solver.horizon();
  ocp->horizon = n;
  ocp->sample_time = solver.settings().sample_time;
  ocp->integrator_steps = solver.settings().integrator_steps;
  ocp->params = solver.problem().params;
  ocp->bounded = solver.layout().indices;
  ocp->lbx.assign(n + 1, Vec<Model::kNx>::Constant(-kInf));
  ocp->ubx.assign(n + 1, Vec<Model::kNx>::Constant(kInf));
  for (int k = 1; k <= n; ++k) {
    ocp->lbx[k] = solver.lower_state_bound(k);
    ocp->ubx[k] = solver.upper_state_bound(k);
  }
  ocp->lbu.resize(n);
  ocp->ubu.resize(n);
  for (int k = 0; k < n; ++k) {
    ocp->lbu[k] = solver.lower_input_bound(k);
    ocp->ubu[k] = solver.upper_input_bound(k);
  }
  ocp->x_guess = solver.states();
  ocp->u_guess = solver.inputs();
}

/// Bounds that are active (within `tol`) at a solution: inputs and bounded states.
struct ActiveBounds {
  int inputs = 0;
  int states = 0;
  double min_margin = kInf;  ///< smallest distance to any bound
  std::string first;         ///< description of the first active bound found
};

template <class Model>
ActiveBounds FindActiveBounds(const ShootingOcp<Model>& ocp, const ShootingSolution<Model>& s,
                              double tol) {
  ActiveBounds a;
  auto check = [&](double v, double lb, double ub, int* count, const std::string& what) {
    const double margin = std::min(v - lb, ub - v);
    a.min_margin = std::min(a.min_margin, margin);
    if (margin < tol) {
      ++*count;
      if (a.first.empty()) a.first = what;
    }
  };
  for (int k = 0; k < ocp.horizon; ++k) {
    for (int i = 0; i < Model::kNu; ++i) {
      check(s.u[k][i], ocp.lbu[k][i], ocp.ubu[k][i], &a.inputs,
            "u_" + std::to_string(k) + "[" + std::to_string(i) + "]");
    }
  }
  for (int k = 1; k <= ocp.horizon; ++k) {
    for (int i : ocp.bounded) {
      check(s.x[k][i], ocp.lbx[k][i], ocp.ubx[k][i], &a.states,
            "x_" + std::to_string(k) + "[" + std::to_string(i) + "]");
    }
  }
  return a;
}

/// Largest deviations between our solver's iterate and IPOPT's optimum.
struct Deviation {
  double states = 0.0;
  double inputs = 0.0;
  int worst_state_node = -1, worst_state_index = -1;
  int worst_input_stage = -1, worst_input_index = -1;
};

template <class Model, class Solver>
Deviation Compare(const Solver& solver, const ShootingSolution<Model>& s) {
  Deviation d;
  for (int k = 0; k <= solver.horizon(); ++k) {
    for (int i = 0; i < Model::kNx; ++i) {
      const double e = std::abs(solver.states()[k][i] - s.x[k][i]);
      if (e > d.states) {
        d.states = e;
        d.worst_state_node = k;
        d.worst_state_index = i;
      }
    }
  }
  for (int k = 0; k < solver.horizon(); ++k) {
    for (int i = 0; i < Model::kNu; ++i) {
      const double e = std::abs(solver.inputs()[k][i] - s.u[k][i]);
      if (e > d.inputs) {
        d.inputs = e;
        d.worst_input_stage = k;
        d.worst_input_index = i;
      }
    }
  }
  return d;
}

// ---- The benchmark problems written out from the spec ----

constexpr double kMass = 1.37;  // [kg] spec vehicle

/// Problem L: y = [p - p_r, v - v_r, phi, theta, T - m g, phi_ref, theta_ref].
ShootingOcp<model::QuadrotorModel> SpecLeaderOcp(const ReferenceTrajectory& ref, double t) {
  ShootingOcp<model::QuadrotorModel> ocp;
  ocp.cx = MatX::Zero(11, 9);
  ocp.cx.topLeftCorner(8, 8).setIdentity();
  ocp.cu = MatX::Zero(11, 3);
  ocp.cu.bottomRows(3).setIdentity();
  ocp.w.resize(11);
  ocp.w << 20, 20, 30, 2, 2, 2, 1, 1, 0.05, 5, 5;
  ocp.cxn = MatX::Zero(8, 9);
  ocp.cxn.leftCols(8).setIdentity();
  ocp.wn.resize(8);
  ocp.wn << 100, 100, 150, 10, 10, 10, 5, 5;
  Vec3 p, v;
  for (int k = 0; k < ocp.horizon; ++k) {
    ref.Sample(t + k * ocp.sample_time, &p, &v);
    VecX target = VecX::Zero(11);
    target.segment<3>(0) = p;
    target.segment<3>(3) = v;
    target[8] = kMass * kGravity;
    ocp.target.push_back(target);
  }
  ref.Sample(t + ocp.horizon * ocp.sample_time, &p, &v);
  ocp.target_n = VecX::Zero(8);
  ocp.target_n.segment<3>(0) = p;
  ocp.target_n.segment<3>(3) = v;
  return ocp;
}

/// Problem F2 (inertial frame). State [v(3), phi, theta, psi, dx_1(3), v_1(3), psi_1, wz_1,
/// dx_2(3), v_2(3), psi_2, wz_2]; y = [dx_1 - d_1, dx_2 - d_2, v_1 - v, v_2 - v, phi, theta,
/// T - m g, phi_ref, theta_ref], terminal: the first 14 entries with 5x the weights.
ShootingOcp<model::FollowerModel<2>> SpecFollowerOcp() {
  ShootingOcp<model::FollowerModel<2>> ocp;
  const std::array<int, 2> dx{6, 14}, vj{9, 17};
  ocp.cx = MatX::Zero(17, 22);
  for (int j = 0; j < 2; ++j) {
    ocp.cx.block(3 * j, dx[j], 3, 3).setIdentity();
    ocp.cx.block(6 + 3 * j, vj[j], 3, 3).setIdentity();
    ocp.cx.block(6 + 3 * j, 0, 3, 3) = -Mat3::Identity();
  }
  ocp.cx(12, 3) = 1.0;
  ocp.cx(13, 4) = 1.0;
  ocp.cu = MatX::Zero(17, 3);
  ocp.cu.bottomRows(3).setIdentity();
  ocp.w.resize(17);
  ocp.w << 20, 20, 30, 20, 20, 30, 2, 2, 2, 2, 2, 2, 1, 1, 0.05, 5, 5;
  VecX target = VecX::Zero(17);
  target << 1, 1, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, kMass * kGravity, 0, 0;
  ocp.target.assign(ocp.horizon, target);
  ocp.cxn = ocp.cx.topRows(14);
  ocp.wn = 5.0 * ocp.w.head(14);
  ocp.target_n = target.head(14);
  return ocp;
}

/// Runs our solver's first call and IPOPT on the same problem and checks agreement.
template <class Model, class Solver>
void ExpectAgreement(Solver* solver, ShootingOcp<Model> ocp, const Vec<Model::kNx>& x0,
                     bool expect_active, const std::string& name) {
  // Given the same NLP for IPOPT (bounds and guess copied from the solver)
  CopySolverData(*solver, &ocp);
  ocp.x0 = x0;
  // When IPOPT solves it to tol 1e-10 and our solver runs its first call
  const ShootingSolution<Model> ref = SolveWithIpopt(ocp);
  ASSERT_EQ(ref.status, Ipopt::Solve_Succeeded) << name;
  Vec<Model::kNu> u0;
  const rti::RtiStatus status = solver->Step(x0, &u0);
  ASSERT_EQ(status, rti::RtiStatus::kSuccess) << name;
  const double kkt = solver->ComputeKkt(x0);
  const Deviation dev = Compare(*solver, ref);
  const ActiveBounds active = FindActiveBounds(ocp, ref, 1e-6);
  std::cout << "[ipopt-ref] " << name << ": ipopt_iter=" << ref.iterations
            << " sqp_iter=" << solver->stats().sqp_iterations << " kkt=" << kkt
            << " max|dx|=" << dev.states << " (node " << dev.worst_state_node << ", comp "
            << dev.worst_state_index << ") max|du|=" << dev.inputs << " (stage "
            << dev.worst_input_stage << ", comp " << dev.worst_input_index
            << ") active_inputs=" << active.inputs << " active_states=" << active.states
            << " min_margin=" << active.min_margin
            << (active.first.empty() ? "" : " first_active=" + active.first) << "\n";
  // Then our iterate converged (KKT < 1e-6) to IPOPT's optimum
  EXPECT_LT(solver->stats().kkt, 1e-6) << name;
  EXPECT_LT(kkt, 1e-6) << name;
  EXPECT_LT(dev.states, 1e-5) << name << ": worst state at node " << dev.worst_state_node
                              << ", component " << dev.worst_state_index;
  EXPECT_LT(dev.inputs, 1e-5) << name << ": worst input at stage " << dev.worst_input_stage
                              << ", component " << dev.worst_input_index;
  EXPECT_TRUE(u0 == solver->inputs()[0]) << name << ": u0 is not the first control";
  // And the case is what it claims: bounds active (or clearly inactive) at the optimum
  if (expect_active) {
    EXPECT_GT(active.inputs + active.states, 0)
        << name << ": no bound active, min margin " << active.min_margin;
  } else {
    EXPECT_EQ(active.inputs + active.states, 0) << name << ": " << active.first;
    EXPECT_GT(active.min_margin, 1e-3) << name;
  }
}

Vec<9> LeaderState(const Vec3& p, const Vec3& v) {
  Vec<9> x = Vec<9>::Zero();
  x.head<3>() = p;
  x.segment<3>(3) = v;
  return x;
}

TEST(RtiIpoptTest, LeaderWithoutActiveBoundsMatchesIpopt) {
  // Given the leader near the nominal reference at t = 2 s (mid-leg, 0.74 m/s)
  const ReferenceTrajectory ref(Scenario::kNominal);
  const double t = 2.0;
  Vec3 p, v;
  ref.Sample(t, &p, &v);
  Vec<9> x0 = LeaderState(p + Vec3(0.1, -0.05, 0.08), v + Vec3(0.05, 0.02, -0.03));
  x0.segment<3>(6) << 0.02, -0.01, 0.03;
  auto solver = MakeLeaderSolver(x0);
  SetLeaderReferences(&solver, ref, t);
  // Then the converged first call equals IPOPT's optimum, no bound active
  ExpectAgreement(&solver, SpecLeaderOcp(ref, t), x0, false, "L/inactive");
}

TEST(RtiIpoptTest, LeaderWithActiveBoundsMatchesIpopt) {
  // Given the leader 3 m from the reference at rest: tilt and velocity bounds bind
  const ReferenceTrajectory ref(Scenario::kNominal);
  const double t = 2.0;
  Vec3 p, v;
  ref.Sample(t, &p, &v);
  const Vec<9> x0 = LeaderState(p + Vec3(3.0, 0.0, 0.0), Vec3::Zero());
  auto solver = MakeLeaderSolver(x0);
  SetLeaderReferences(&solver, ref, t);
  // Then the converged first call equals IPOPT's optimum, with bounds active
  ExpectAgreement(&solver, SpecLeaderOcp(ref, t), x0, true, "L/active");
}

/// Follower neighbours: leader at rel1 with velocity vel, neighbour 2 at rel1 + (-1, 1, 0).
std::array<NeighbourState, 2> Neighbours(const Vec3& rel1, const Vec3& vel) {
  return {NeighbourState{rel1, vel, 0.0, 0.0},
          NeighbourState{rel1 + kNeighbour2Shift, vel, 0.0, 0.0}};
}

TEST(RtiIpoptTest, FollowerWithoutActiveBoundsMatchesIpopt) {
  // Given the follower close to its formation slot, neighbours moving at 0.7 m/s
  const Vec3 vel(0.5, 0.4, 0.25);
  const auto nb = Neighbours(kD1 + Vec3(0.08, -0.06, 0.05), vel);
  Vec<6> own;
  own.head<3>() = vel + Vec3(-0.1, 0.05, 0.02);
  own.tail<3>() << 0.02, -0.03, 0.01;
  auto solver = MakeFollowerSolver<2>(own, nb);
  const Vec<22> x0 = FollowerState<2>(own, nb);
  // Then the converged first call equals IPOPT's optimum, no bound active
  ExpectAgreement(&solver, SpecFollowerOcp(), x0, false, "F2/inactive");
}

TEST(RtiIpoptTest, FollowerFarFromFormationMatchesIpopt) {
  // Given the follower 4.3 m from its slot, at rest, static neighbours: inputs and the
  // velocity bound become active
  const auto nb = Neighbours(kD1 + Vec3(3.0, -2.5, 1.0), Vec3::Zero());
  const Vec<6> own = Vec<6>::Zero();
  auto solver = MakeFollowerSolver<2>(own, nb);
  const Vec<22> x0 = FollowerState<2>(own, nb);
  // Then the converged first call equals IPOPT's optimum, with bounds active
  ExpectAgreement(&solver, SpecFollowerOcp(), x0, true, "F2/far");
}

TEST(RtiIpoptTest, FollowerWithActiveRelativePositionBoundMatchesIpopt) {
  // Given the follower 1 m behind its slot in x and a tightened (soft) relative-position
  // bound dx_1,x >= 1.8 that stops it half-way: the hard problem stays feasible (the
  // follower starts at dx_1,x = 2) and the exact penalty must reproduce its optimum
  const auto nb = Neighbours(kD1 + Vec3(1.0, 0.0, 0.0), Vec3::Zero());
  const Vec<6> own = Vec<6>::Zero();
  auto solver = MakeFollowerSolver<2>(own, nb);
  const int dx1 = model::FollowerModel<2>::Neighbour(0);
  for (int k = 1; k <= solver.horizon(); ++k) {
    Vec<22> lb = solver.lower_state_bound(k);
    lb[dx1] = 1.8;
    solver.SetStateBounds(k, lb, solver.upper_state_bound(k));
  }
  const Vec<22> x0 = FollowerState<2>(own, nb);
  auto ocp = SpecFollowerOcp();
  // Then the converged first call equals IPOPT's optimum, with the bound active
  ExpectAgreement(&solver, ocp, x0, true, "F2/relative-bound");
  double closest = kInf, max_slack = 0.0;
  for (int k = 1; k <= solver.horizon(); ++k) {
    closest = std::min(closest, solver.states()[k][dx1] - 1.8);
    max_slack = std::max(max_slack, solver.slack(k));
  }
  EXPECT_LT(max_slack, 1e-9) << "the exact penalty left the bound relaxed";
  EXPECT_LT(std::abs(closest), 1e-6) << "the relative-position bound is not active";
}

}  // namespace
}  // namespace fnmpc::bench

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Deterministic QP generators and an independent KKT check shared by the QP tests and
// the QP benchmark. Everything is built from a caller-seeded std::mt19937.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "fnmpc/qp/dense_qp.hpp"

namespace fnmpc::qp::testing {

/// +infinity, the "absent" bound.
inline constexpr double kInfBound = std::numeric_limits<double>::infinity();

/// Matrix with i.i.d. standard normal entries.
inline Eigen::MatrixXd Gaussian(int rows, int cols, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::MatrixXd m(rows, cols);
  for (int c = 0; c < cols; ++c) {
    for (int r = 0; r < rows; ++r) m(r, c) = n(*rng);
  }
  return m;
}

/// Uniform sample in [lo, hi].
inline double Uniform(double lo, double hi, std::mt19937* rng) {
  return std::uniform_real_distribution<double>(lo, hi)(*rng);
}

/// Symmetric positive definite matrix M M' / n + min_eig I (eigenvalues >= min_eig).
inline Eigen::MatrixXd RandomSpd(int n, double min_eig, std::mt19937* rng) {
  const Eigen::MatrixXd m = Gaussian(n, n, rng);
  Eigen::MatrixXd h = m * m.transpose() / n;
  h.diagonal().array() += min_eig;
  return 0.5 * (h + h.transpose());
}

/// Options of RandomFeasibleQp.
struct RandomQpOptions {
  double g_scale = 10.0;         ///< scale of the linear term (large -> many active constraints)
  double equality_share = 0.0;   ///< share of general rows turned into equalities
  double one_sided_share = 0.3;  ///< share of constraints with one infinite side
  double bound_width = 1.0;      ///< largest distance of a bound from x_feasible
  double row_width = 2.0;        ///< largest distance of a row side from A x_feasible
};

/// Random strictly convex QP whose constraints all hold at a known point x_feasible.
inline DenseQp RandomFeasibleQp(int nv, int nc, std::mt19937* rng, const RandomQpOptions& opt = {},
                                Eigen::VectorXd* x_feasible = nullptr) {
  DenseQp qp(DenseQpDims{nv, nc});
  qp.H = RandomSpd(nv, 0.1, rng);
  qp.g = opt.g_scale * Gaussian(nv, 1, rng);
  Eigen::VectorXd xf(nv);
  for (int j = 0; j < nv; ++j) xf[j] = Uniform(-1.0, 1.0, rng);
  const auto sides = [&](double center, double* lo, double* hi, double width) {
    *lo = center - Uniform(0.05, width, rng);
    *hi = center + Uniform(0.05, width, rng);
    const double p = Uniform(0.0, 1.0, rng);
    if (p < 0.5 * opt.one_sided_share) {
      *lo = -kInfBound;
    } else if (p < opt.one_sided_share) {
      *hi = kInfBound;
    }
  };
  for (int j = 0; j < nv; ++j) sides(xf[j], &qp.lb[j], &qp.ub[j], opt.bound_width);
  if (nc > 0) {
    qp.A = Gaussian(nc, nv, rng);
    const Eigen::VectorXd ax = qp.A * xf;
    for (int i = 0; i < nc; ++i) {
      if (Uniform(0.0, 1.0, rng) < opt.equality_share) {
        qp.lbA[i] = qp.ubA[i] = ax[i];
      } else {
        sides(ax[i], &qp.lbA[i], &qp.ubA[i], opt.row_width);
      }
    }
  }
  if (x_feasible != nullptr) *x_feasible = xf;
  return qp;
}

/// KKT residuals recomputed from the data (independent of the solver's own function).
struct IndependentKkt {
  double stationarity = 0.0;     ///< |H x + g + y_b + A' y_c|_inf
  double primal = 0.0;           ///< largest bound / constraint violation
  double dual = 0.0;             ///< largest multiplier of the wrong sign (or on an absent side)
  double complementarity = 0.0;  ///< largest |y| * distance to the side it acts on
  [[nodiscard]] double Max() const {
    return std::max(std::max(stationarity, primal), std::max(dual, complementarity));
  }
};

/// Checks one row value against [lo, hi] with multiplier y (y > 0 upper, y < 0 lower).
inline void CheckSide(double value, double lo, double hi, double y, IndependentKkt* k) {
  k->primal = std::max(k->primal, std::max(0.0, std::max(lo - value, value - hi)));
  if (lo == hi) return;
  if (y > 0.0) {
    k->dual = std::isfinite(hi) ? k->dual : std::max(k->dual, y);
    if (std::isfinite(hi)) k->complementarity = std::max(k->complementarity, y * (hi - value));
  } else if (y < 0.0) {
    k->dual = std::isfinite(lo) ? k->dual : std::max(k->dual, -y);
    if (std::isfinite(lo)) k->complementarity = std::max(k->complementarity, -y * (value - lo));
  }
}

/// Recomputes all KKT residuals of (x, y) for qp.
inline IndependentKkt CheckKkt(const DenseQp& qp, const QpSolution& s) {
  IndependentKkt k;
  Eigen::VectorXd r = qp.H * s.x + qp.g + s.y_bounds;
  if (qp.A.rows() > 0) r += qp.A.transpose() * s.y_constraints;
  k.stationarity = r.cwiseAbs().maxCoeff();
  for (int j = 0; j < qp.g.size(); ++j) CheckSide(s.x[j], qp.lb[j], qp.ub[j], s.y_bounds[j], &k);
  for (int i = 0; i < qp.A.rows(); ++i) {
    CheckSide(qp.A.row(i).dot(s.x), qp.lbA[i], qp.ubA[i], s.y_constraints[i], &k);
  }
  return k;
}

/// Condensed 1-D double-integrator MPC (like one axis of the RTI problem): inputs are
/// accelerations u_k (|u_k| <= u_max, box bounds), positions p_k <= p_max are general rows.
struct MpcQpFactory {
  int horizon = 45;     ///< number of inputs (nv)
  double dt = 0.1;      ///< step [s]
  double u_max = 1.0;   ///< acceleration bound [m/s^2]
  double p_max = 1.2;   ///< position limit [m]
  double w_pos = 10.0;  ///< position weight
  double w_vel = 1.0;   ///< velocity weight
  double w_u = 0.05;    ///< input weight
  double p_ref = 2.0;   ///< position reference [m]

  /// QP for initial position p0 [m] and velocity v0 [m/s].
  [[nodiscard]] DenseQp Build(double p0, double v0) const {
    const int n = horizon;
    DenseQp qp(DenseQpDims{n, n});
    // p_{k+1} = p0 + (k+1) dt v0 + sum_{j<=k} G_kj u_j, v_{k+1} = v0 + dt sum_{j<=k} u_j.
    Eigen::MatrixXd gp = Eigen::MatrixXd::Zero(n, n);
    Eigen::MatrixXd gv = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd fp(n);
    Eigen::VectorXd fv(n);
    for (int k = 0; k < n; ++k) {
      fp[k] = p0 + (k + 1) * dt * v0;
      fv[k] = v0;
      for (int j = 0; j <= k; ++j) {
        gp(k, j) = dt * dt * (k - j + 0.5);
        gv(k, j) = dt;
      }
    }
    qp.H = w_pos * gp.transpose() * gp + w_vel * gv.transpose() * gv;
    qp.H.diagonal().array() += w_u;
    qp.g = w_pos * gp.transpose() * (fp - Eigen::VectorXd::Constant(n, p_ref)) +
           w_vel * gv.transpose() * fv;
    qp.lb.setConstant(-u_max);
    qp.ub.setConstant(u_max);
    qp.A = gp;
    qp.ubA = Eigen::VectorXd::Constant(n, p_max) - fp;
    return qp;
  }

  /// Applies u0 to the plant for one step.
  void Step(double u0, double* p, double* v) const {
    *p += dt * *v + 0.5 * dt * dt * u0;
    *v += dt * u0;
  }
};

}  // namespace fnmpc::qp::testing

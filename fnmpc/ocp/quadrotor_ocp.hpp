// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>

#include "fnmpc/core/types.hpp"
#include "fnmpc/ocp/nmpc_weights.hpp"
#include "fnmpc/rti/rti_settings.hpp"

/// How the quadrotor OCPs of fnmpc/ocp/problems.hpp are set up on an rti::RtiSolver: weight
/// rows, bounded states, input and speed bounds, the reduced follower's displacement bounds.
/// One module for both users, the formation controllers (fnmpc/formation/nmpc_core.cpp,
/// whose problems add obstacle and input-rate rows after these) and the fixed benchmark
/// problems (bench/ocp_spec/benchmark_ocps.cpp, docs/benchmark-spec.md: the defaults of
/// ocp::NmpcWeights and of formation::ControllerSettings' bounds). Here, in the quadrotor's
/// layer, and templated on the solver: the solver layer (fnmpc/rti) knows no quadrotor.
namespace fnmpc::ocp::quadrotor {

/// Input bounds [T, roll_ref, pitch_ref] on every stage: thrust in [min, max] [N], the
/// attitude references within +-max_attitude_ref [rad], moved by `shift` [rad] (roll, pitch;
/// a controller that sends u - shift keeps the reference it sends within the bound). Hard (the
/// QP keeps them exactly).
template <class Solver>
void SetInputLimits(Solver* solver, double thrust_min, double thrust_max, double max_attitude_ref,
                    const Vec<2>& shift = Vec<2>::Zero()) {
  const Vec3 lo(thrust_min, -max_attitude_ref + shift[0], -max_attitude_ref + shift[1]);
  const Vec3 hi(thrust_max, max_attitude_ref + shift[0], max_attitude_ref + shift[1]);
  for (int k = 0; k < solver->horizon(); ++k) solver->SetInputBounds(k, lo, hi);
}

/// +-max_speed [m/s] on the three velocity components from state `first` on (leader and
/// reduced follower: 3, full follower: 0); the other entries of lb, ub are left as they are.
template <class X>
void SetSpeedBounds(int first, double max_speed, X* lb, X* ub) {
  lb->template segment<3>(first).setConstant(-max_speed);
  ub->template segment<3>(first).setConstant(max_speed);
}

/// LeaderProblem's stage rows p - p_ref, v - v_ref, roll, pitch, T - m g, roll_ref, pitch_ref.
inline Vec<11> LeaderWeights(const ocp::NmpcWeights& w) {
  Vec<11> rows;
  rows << w.position, w.velocity, w.attitude, w.attitude, w.thrust, w.attitude_ref, w.attitude_ref;
  return rows;
}
/// Its terminal rows (position, velocity, roll, pitch): terminal_factor times the stage's.
inline Vec<8> LeaderTerminalWeights(const ocp::NmpcWeights& w) {
  return w.terminal_factor * LeaderWeights(w).head<8>();
}

/// FollowerProblem<Nn>'s and ReducedFollowerProblem<Nn>'s stage rows: dx_j - d_j and v_j - v
/// of the first `weighted` neighbours (the others' rows 0), then roll, pitch, T - m g,
/// roll_ref, pitch_ref.
template <int Nn>
Vec<6 * Nn + 5> FollowerWeights(const ocp::NmpcWeights& w, int weighted = Nn) {
  Vec<6 * Nn + 5> rows = Vec<6 * Nn + 5>::Zero();
  for (int j = 0; j < std::min(weighted, Nn); ++j) {
    rows.template segment<3>(3 * j) = w.position;
    rows.template segment<3>(3 * Nn + 3 * j) = w.velocity;
  }
  rows.template tail<5>() << w.attitude, w.attitude, w.thrust, w.attitude_ref, w.attitude_ref;
  return rows;
}
/// Their terminal rows (all but the last three): terminal_factor times the stage's.
template <int Nn>
Vec<6 * Nn + 2> FollowerTerminalWeights(const ocp::NmpcWeights& w, int weighted = Nn) {
  return w.terminal_factor * FollowerWeights<Nn>(w, weighted).template head<6 * Nn + 2>();
}

/// LeaderProblem's bounded states (p, v, angles): the velocity, and the altitude z with
/// `altitude`; all soft (exact-penalty slacks: no state makes the QP infeasible) or all hard.
inline rti::StateBoundLayout LeaderLayout(bool altitude, bool soft) {
  rti::StateBoundLayout layout;
  for (int i = altitude ? 2 : 3; i < 6; ++i) {
    layout.indices.push_back(i);
    layout.soft.push_back(soft);
  }
  return layout;
}

/// ReducedFollowerProblem's bounded states: the displacement s (soft: it carries the
/// neighbours' relative-position bounds) and the velocity (soft with `soft_velocity`).
inline rti::StateBoundLayout ReducedFollowerLayout(bool soft_velocity) {
  return {{0, 1, 2, 3, 4, 5}, {true, true, true, soft_velocity, soft_velocity, soft_velocity}};
}

/// The reduced follower's relative-position bound of one neighbour at one stage, -b <= c - s
/// <= b with c its predicted relative position, as bounds on the displacement s: [lo, hi] is
/// intersected with [c - b, c + b] (start from (-inf, inf); one call per neighbour).
inline void IntersectRelativeBound(const Vec3& c, const Vec3& b, Vec3* lo, Vec3* hi) {
  *lo = lo->cwiseMax(c - b);
  *hi = hi->cwiseMin(c + b);
}

}  // namespace fnmpc::ocp::quadrotor

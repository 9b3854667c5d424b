// SPDX-License-Identifier: BSD-3-Clause
// A quadrotor leader (problem L of docs/rti.md: position, velocity, roll, pitch, yaw; inputs
// collective thrust and roll/pitch references) flies through four waypoints, holding each
// for 4 s, with RTI in closed loop at 20 Hz and the speed bounded to 2 m/s. The plant is the
// prediction model itself (fnmpc/model/quadrotor_model.hpp, the reference work's Eqs. (2)-(4)).
#include <array>
#include <cmath>
#include <cstdio>

#include "fnmpc/model/quadrotor_model.hpp"
#include "fnmpc/model/rk4.hpp"
#include "fnmpc/ocp/problems.hpp"
#include "fnmpc/rti/rti_solver.hpp"

using namespace fnmpc;

int main() {
  ocp::LeaderProblem problem;  // default vehicle: 1.37 kg, identified attitude dynamics
  rti::RtiSettings settings;   // N = 15, Ts = 0.05 s, 2 RK4 steps per interval
  // Velocity (state components 3..5) bounded at every node.
  rti::RtiSolver<ocp::LeaderProblem> solver(problem, settings, {{3, 4, 5}, {false, false, false}});
  Vec<11> w;  // p, v, phi, theta, T - m g, phi_ref, theta_ref
  w << 20, 20, 30, 2, 2, 2, 1, 1, 0.05, 5, 5;
  Vec<8> wn;  // p, v, phi, theta
  wn << 100, 100, 150, 10, 10, 10, 5, 5;
  solver.SetWeights(w, wn);
  const double hover = problem.params.mass * kGravity;
  Vec<9> lbx = Vec<9>::Constant(-kInf), ubx = Vec<9>::Constant(kInf);
  lbx.segment<3>(3).setConstant(-2.0);
  ubx.segment<3>(3).setConstant(2.0);
  for (int k = 0; k < settings.horizon; ++k) {
    solver.SetInputBounds(k, Vec3(5, -0.35, -0.35), Vec3(25, 0.35, 0.35));
    solver.SetStateBounds(k + 1, lbx, ubx);
  }
  const std::array<Vec3, 4> waypoints{Vec3(2, 0, 1.5), Vec3(2, 2, 1), Vec3(0, 2, 2), Vec3(0, 0, 1)};
  Vec<9> x = Vec<9>::Zero();
  x[2] = 1.0;  // start hovering at 1 m
  solver.InitializeGuess(x, Vec3(hover, 0, 0));
  const int steps_per_waypoint = static_cast<int>(4.0 / settings.sample_time);
  double max_speed = 0.0;
  bool ok = true;
  for (std::size_t i = 0; i < waypoints.size(); ++i) {
    Vec<11> y = Vec<11>::Zero();
    y.head<3>() = waypoints[i];
    Vec<8> yn = Vec<8>::Zero();
    yn.head<3>() = waypoints[i];
    for (int k = 0; k < settings.horizon; ++k) solver.SetReference(k, y);
    solver.SetTerminalReference(yn);
    for (int s = 0; s < steps_per_waypoint; ++s) {
      Vec3 u;
      if (solver.Step(x, &u) != rti::RtiStatus::kSuccess) {
        std::printf("solver failed at waypoint %zu\n", i);
        return 1;
      }
      solver.Shift();
      x = model::Rk4<model::QuadrotorModel>(x, u, 0.0, problem.params, settings.sample_time, 10);
      max_speed = std::max(max_speed, x.segment<3>(3).cwiseAbs().maxCoeff());
    }
    const double error = (x.head<3>() - waypoints[i]).norm();
    std::printf("waypoint %zu (%.1f, %.1f, %.1f): reached to %.3f m after 4 s\n", i,
                waypoints[i].x(), waypoints[i].y(), waypoints[i].z(), error);
    ok = ok && error < 0.05;
  }
  // The bound holds at the prediction's nodes; the plant may exceed it slightly between
  // them, so the check allows 5 %.
  std::printf("largest speed along an axis %.3f m/s (bound 2 m/s)\n", max_speed);
  return ok && max_speed < 2.0 * 1.05 ? 0 : 1;
}

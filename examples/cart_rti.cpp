// SPDX-License-Identifier: BSD-3-Clause
// A cart on a rail, x = [position (m), velocity (m/s)], u = [force (N)], pushed from rest at
// 0 m to 1 m by RTI in closed loop with |u| <= 1 N.
#include <cmath>
#include <cstdio>

#include "fnmpc/core/rk4.hpp"
#include "fnmpc/rti/rti_solver.hpp"

using namespace fnmpc;

struct Cart {  // the solver's problem contract: docs/rti.md
  static constexpr int kNx = 2, kNu = 1, kNy = 3, kNyN = 2;
  struct Params {};                   // no per-stage online data
  double mass = 2.0, friction = 0.5;  // [kg], [N s/m]
  Vec<2> Discretise(const Vec<2>& x, const Vec<1>& u, const Params&, double dt, int steps,
                    Mat<2, 2>* A, Mat<2, 1>* B) const {
    auto flow = [&](const Vec<2>& s, const Vec<1>& f, Vec<2>* xdot, Mat<2, 2>* fx, Mat<2, 1>* fu) {
      *xdot << s[1], (f[0] - friction * s[1]) / mass;
      if (fx != nullptr) *fx << 0, 1, 0, -friction / mass;
      if (fu != nullptr) *fu << 0, 1 / mass;
    };
    return IntegrateRk4(flow, x, u, dt, steps, A, B);
  }
  // y = [position, velocity, force], yN = [position, velocity].
  void StageResidual(const Vec<2>& x, const Vec<1>& u, const Params&, Vec<3>* y, Mat<3, 2>* yx,
                     Mat<3, 1>* yu) const {
    *y << x, u;
    if (yx != nullptr) yx->topRows<2>().setIdentity();
    if (yu != nullptr) (*yu)(2, 0) = 1;
  }
  void TerminalResidual(const Vec<2>& x, const Params&, Vec<2>* y, Mat<2, 2>* yx) const {
    *y = x;
    if (yx != nullptr) yx->setIdentity();
  }
};

int main() {
  rti::RtiSettings settings;
  settings.horizon = 20, settings.sample_time = 0.1;
  rti::RtiSolver<Cart> solver(Cart{}, settings, rti::StateBoundLayout{});
  solver.SetWeights(Vec<3>(10, 1, 0.1), Vec<2>(100, 10));
  for (int k = 0; k < settings.horizon; ++k) {
    solver.SetReference(k, Vec<3>(1, 0, 0));
    solver.SetInputBounds(k, Vec<1>(-1), Vec<1>(1));
  }
  solver.SetTerminalReference(Vec<2>(1, 0));
  Vec<2> x = Vec<2>::Zero();
  solver.InitializeGuess(x, Vec<1>::Zero());
  double max_force = 0;
  for (int t = 0; t < 100; ++t, solver.Shift()) {  // 10 s
    Vec<1> u;
    if (solver.Step(x, &u) != rti::RtiStatus::kSuccess) return std::puts("solver failed"), 1;
    max_force = std::max(max_force, std::abs(u[0]));
    x = Cart{}.Discretise(x, u, {}, settings.sample_time, 10, nullptr, nullptr);  // the plant
  }
  std::printf("cart after 10 s: %.4f m, %.4f m/s; max |force| %.3f N\n", x[0], x[1], max_force);
  return std::abs(x[0] - 1) < 0.01 && std::abs(x[1]) < 0.01 && max_force <= 1 + 1e-9 ? 0 : 1;
}

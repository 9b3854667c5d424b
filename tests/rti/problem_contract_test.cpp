// SPDX-License-Identifier: BSD-3-Clause
// The solver's problem contract (docs/rti.md) with models that are not quadrotors: one
// input, one state, a user-defined (or empty) per-stage parameter type, the generic
// integrator IntegrateRk4 (its own test: tests/core/rk4_test.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/core/rk4.hpp"
#include "fnmpc/rti/rti_solver.hpp"
#include "tests/support/numeric_jacobian.hpp"

namespace fnmpc::rti {
namespace {

// Double integrator (a point mass on a line): x = [position, velocity], u = [force / mass].
// Params: the position reference of each stage, a user type that is not an Eigen vector.
struct PointMass {
  static constexpr int kNx = 2, kNu = 1, kNy = 3, kNyN = 2;
  struct Params {
    double target = 0.0;  ///< [m]
  };

  Vec<2> Discretise(const Vec<2>& x, const Vec<1>& u, const Params& /*p*/, double dt, int steps,
                    Mat<2, 2>* A, Mat<2, 1>* B) const {
    auto flow = [](const Vec<2>& s, const Vec<1>& a, Vec<2>* f, Mat<2, 2>* fx, Mat<2, 1>* fu) {
      *f << s[1], a[0];
      if (fx != nullptr) (*fx)(0, 1) = 1.0;
      if (fu != nullptr) (*fu)(1, 0) = 1.0;
    };
    return IntegrateRk4(flow, x, u, dt, steps, A, B);
  }
  void StageResidual(const Vec<2>& x, const Vec<1>& u, const Params& p, Vec<3>* y, Mat<3, 2>* yx,
                     Mat<3, 1>* yu) const {
    *y << x[0] - p.target, x[1], u[0];
    if (yx != nullptr) {
      yx->topRows<2>().setIdentity();
      (*yu)(2, 0) = 1.0;
    }
  }
  void TerminalResidual(const Vec<2>& x, const Params& p, Vec<2>* y, Mat<2, 2>* yx) const {
    *y << x[0] - p.target, x[1];
    if (yx != nullptr) yx->setIdentity();
  }
};

// A scalar nonlinear system, x' = -x^3 + u, with no parameters at all.
struct Scalar {
  static constexpr int kNx = 1, kNu = 1, kNy = 2, kNyN = 1;
  struct Params {};

  Vec<1> Discretise(const Vec<1>& x, const Vec<1>& u, const Params& /*p*/, double dt, int steps,
                    Mat<1, 1>* A, Mat<1, 1>* B) const {
    auto flow = [](const Vec<1>& s, const Vec<1>& v, Vec<1>* f, Mat<1, 1>* fx, Mat<1, 1>* fu) {
      (*f)[0] = -s[0] * s[0] * s[0] + v[0];
      if (fx != nullptr) (*fx)(0, 0) = -3.0 * s[0] * s[0];
      if (fu != nullptr) (*fu)(0, 0) = 1.0;
    };
    return IntegrateRk4(flow, x, u, dt, steps, A, B);
  }
  void StageResidual(const Vec<1>& x, const Vec<1>& u, const Params& /*p*/, Vec<2>* y,
                     Mat<2, 1>* yx, Mat<2, 1>* yu) const {
    *y << x[0], u[0];
    if (yx != nullptr) {
      (*yx)(0, 0) = 1.0;
      (*yu)(1, 0) = 1.0;
    }
  }
  void TerminalResidual(const Vec<1>& x, const Params& /*p*/, Vec<1>* y, Mat<1, 1>* yx) const {
    *y = x;
    if (yx != nullptr) (*yx)(0, 0) = 1.0;
  }
};

// The point mass with a fault at the stages whose parameter names one: NaN or Inf in the
// interval map's sensitivities, in the next state, or in a stage residual.
struct FaultyPointMass {
  static constexpr int kNx = 2, kNu = 1, kNy = 3, kNyN = 2;
  enum Fault : int { kNone, kNanInA, kInfInB, kNanNextState, kNanWeightedRow, kNanUnweightedRow };
  struct Params {
    Fault fault = kNone;
  };

  Vec<2> Discretise(const Vec<2>& x, const Vec<1>& u, const Params& p, double dt, int steps,
                    Mat<2, 2>* A, Mat<2, 1>* B) const {
    Vec<2> next = PointMass{}.Discretise(x, u, {}, dt, steps, A, B);
    if (A != nullptr && p.fault == kNanInA) (*A)(0, 1) = kNaN;
    if (B != nullptr && p.fault == kInfInB) (*B)(1, 0) = kInf;
    if (p.fault == kNanNextState) next[1] = kNaN;
    return next;
  }
  void StageResidual(const Vec<2>& x, const Vec<1>& u, const Params& p, Vec<3>* y, Mat<3, 2>* yx,
                     Mat<3, 1>* yu) const {
    PointMass{}.StageResidual(x, u, {}, y, yx, yu);
    if (p.fault == kNanWeightedRow) (*y)[0] = kNaN;
    if (p.fault == kNanUnweightedRow) (*y)[1] = kNaN;
  }
  void TerminalResidual(const Vec<2>& x, const Params& /*p*/, Vec<2>* y, Mat<2, 2>* yx) const {
    PointMass{}.TerminalResidual(x, {}, y, yx);
  }
};

RtiSettings Settings(int horizon, double ts) {
  RtiSettings s;
  s.horizon = horizon;
  s.sample_time = ts;
  return s;
}

TEST(ProblemContractTest, SingleInputFirstControlIsTheLqrControl) {
  // Given an unconstrained linear-quadratic problem: its QP is the finite-horizon LQR problem
  const int n = 20;
  const double ts = 0.1;
  RtiSolver<PointMass> solver(PointMass{}, Settings(n, ts), StateBoundLayout{});
  const Vec<3> w(10.0, 1.0, 0.1);
  const Vec<2> wn(100.0, 10.0);
  solver.SetWeights(w, wn);
  const Vec<2> x0(1.0, 0.0);
  solver.InitializeGuess(x0, Vec<1>::Zero());
  // When the solver runs its first call
  Vec<1> u;
  ASSERT_EQ(solver.Step(x0, &u), RtiStatus::kSuccess);
  // Then u equals the first control of the Riccati recursion on the same discretisation
  Mat<2, 2> A;
  Mat<2, 1> B;
  PointMass{}.Discretise(Vec<2>::Zero(), Vec<1>::Zero(), {}, ts, RtiSettings{}.integrator_steps, &A,
                         &B);
  const Mat<2, 2> Q = w.head<2>().asDiagonal();
  Mat<2, 2> P = wn.asDiagonal();
  Mat<1, 2> K;
  for (int k = n - 1; k >= 0; --k) {
    const double r = w[2] + (B.transpose() * P * B)(0, 0);
    K = (B.transpose() * P * A) / r;
    P = Q + A.transpose() * P * A - K.transpose() * r * K;
  }
  EXPECT_NEAR(u[0], -(K * x0)(0, 0), 1e-9);
  EXPECT_LT(solver.stats().kkt, RtiSettings{}.kkt_threshold);
}

TEST(ProblemContractTest, SingleInputClosedLoopReachesStageParameterTarget) {
  // Given the point mass at rest at 0 with the target 0.5 m in every stage's parameters and
  // the input bounded by 0.5
  const int n = 20;
  const double ts = 0.1;
  RtiSolver<PointMass> solver(PointMass{}, Settings(n, ts), StateBoundLayout{{1}, {false}});
  solver.SetWeights(Vec<3>(10.0, 1.0, 0.1), Vec<2>(100.0, 10.0));
  for (int k = 0; k <= n; ++k) solver.SetParameters(k, PointMass::Params{0.5});
  for (int k = 0; k < n; ++k) solver.SetInputBounds(k, Vec<1>(-0.5), Vec<1>(0.5));
  Vec<2> lbx(-kInf, -0.3), ubx(kInf, 0.3);  // and the speed bounded by 0.3 m/s
  for (int k = 1; k <= n; ++k) solver.SetStateBounds(k, lbx, ubx);
  Vec<2> x = Vec<2>::Zero();
  solver.InitializeGuess(x, Vec<1>::Zero());
  // When RTI runs in closed loop for 8 s, the plant being the model
  double max_input = 0.0, max_speed = 0.0;
  for (int t = 0; t < 80; ++t) {
    Vec<1> u;
    ASSERT_EQ(solver.Step(x, &u), RtiStatus::kSuccess) << "t = " << t;
    solver.Shift();
    max_input = std::max(max_input, std::abs(u[0]));
    x = PointMass{}.Discretise(x, u, {}, ts, 4, nullptr, nullptr);
    max_speed = std::max(max_speed, std::abs(x[1]));
  }
  // Then it settles at the target with the input bound respected and active at the start
  EXPECT_NEAR(x[0], 0.5, 1e-3);
  EXPECT_NEAR(x[1], 0.0, 1e-3);
  EXPECT_LE(max_input, 0.5 + 1e-9);
  EXPECT_NEAR(max_input, 0.5, 1e-9);
  EXPECT_LT(max_speed, 0.3 + 0.01);
}

TEST(ProblemContractTest, ScalarStateWithEmptyParamsConverges) {
  // Given x' = -x^3 + u from x = 1.5, regulated to 0
  RtiSolver<Scalar> solver(Scalar{}, Settings(10, 0.1), StateBoundLayout{});
  solver.SetWeights(Vec<2>(1.0, 0.1), Vec<1>(10.0));
  Vec<1> x(1.5);
  solver.InitializeGuess(x, Vec<1>::Zero());
  Vec<1> u;
  // When the first call iterates (nonlinear: several SQP iterations) and RTI then runs 5 s
  ASSERT_EQ(solver.Step(x, &u), RtiStatus::kSuccess);
  EXPECT_GT(solver.stats().sqp_iterations, 1);
  EXPECT_LT(solver.stats().kkt, RtiSettings{}.kkt_threshold);
  for (int t = 0; t < 50; ++t) {
    x = Scalar{}.Discretise(x, u, {}, 0.1, 4, nullptr, nullptr);
    solver.Shift();
    ASSERT_EQ(solver.Step(x, &u), RtiStatus::kSuccess);
  }
  // Then the state is regulated
  EXPECT_LT(std::abs(x[0]), 0.05);
}

TEST(ProblemContractTest, NonFiniteLinearisationFallsBackWithAFiniteCommand) {
  using F = FaultyPointMass;
  for (const F::Fault fault :
       {F::kNanInA, F::kInfInB, F::kNanNextState, F::kNanWeightedRow, F::kNanUnweightedRow}) {
    // Given the point mass with a fault at stage 4 of 10, the velocity row unweighted
    RtiSolver<F> solver(F{}, Settings(10, 0.1), StateBoundLayout{});
    solver.SetWeights(Vec<3>(10.0, 0.0, 0.1), Vec<2>(100.0, 10.0));
    solver.SetParameters(4, F::Params{fault});
    const Vec<2> x0(1.0, 0.0);
    solver.InitializeGuess(x0, Vec<1>(0.25));
    // When the solver runs its first call
    Vec<1> u;
    const RtiStatus status = solver.Step(x0, &u);
    // Then NaN or Inf in the QP data is detected and the guess's first control applied, while
    // NaN in a residual row of zero weight does not enter the QP
    SCOPED_TRACE("fault " + std::to_string(fault));
    EXPECT_TRUE(u.allFinite());
    if (fault == F::kNanUnweightedRow) {
      EXPECT_EQ(status, RtiStatus::kSuccess);
      EXPECT_FALSE(solver.stats().fallback);
    } else {
      EXPECT_EQ(status, RtiStatus::kNanDetected);
      EXPECT_TRUE(solver.stats().fallback);
      EXPECT_EQ(u[0], 0.25);
    }
  }
}

TEST(ProblemContractTest, SettersRejectBadArgumentsAtSetup) {
  // Given a solver with N = 5
  RtiSolver<PointMass> solver(PointMass{}, Settings(5, 0.1), StateBoundLayout{{1}, {false}});
  const Vec<2> lb(-1.0, -1.0), ub(1.0, 1.0);
  // Then stage indices outside their range are refused, naming the setter
  EXPECT_THROW(solver.SetReference(5, Vec<3>::Zero()), std::out_of_range);
  EXPECT_THROW(solver.SetReference(-1, Vec<3>::Zero()), std::out_of_range);
  EXPECT_THROW(solver.SetInputBounds(5, Vec<1>(-1), Vec<1>(1)), std::out_of_range);
  EXPECT_THROW(solver.SetStateBounds(0, lb, ub), std::out_of_range);  // x_0 is fixed
  EXPECT_THROW(solver.SetStateBounds(6, lb, ub), std::out_of_range);
  EXPECT_THROW(solver.SetParameters(6, PointMass::Params{}), std::out_of_range);
  EXPECT_THROW(solver.SetInputBounds(-1, Vec<1>(-1), Vec<1>(1)), std::out_of_range);
  EXPECT_THROW(solver.SetParameters(-1, PointMass::Params{}), std::out_of_range);
  try {
    solver.SetReference(7, Vec<3>::Zero());
    ADD_FAILURE() << "SetReference(7) accepted";
  } catch (const std::out_of_range& e) {
    EXPECT_NE(std::string(e.what()).find("SetReference: stage 7 outside 0..4"), std::string::npos)
        << e.what();
  }
  // and so are negative or NaN weights
  EXPECT_THROW(solver.SetWeights(Vec<3>(1.0, -1.0, 1.0), Vec<2>::Ones()), std::invalid_argument);
  EXPECT_THROW(solver.SetWeights(Vec<3>::Ones(), Vec<2>(1.0, kNaN)), std::invalid_argument);
  EXPECT_THROW(solver.SetWeightValues(Vec<3>(kNaN, 1.0, 1.0), Vec<2>::Ones()),
               std::invalid_argument);
  EXPECT_THROW(solver.SetWeights(Vec<3>(1.0, kInf, 1.0), Vec<2>::Ones()), std::invalid_argument);
  try {
    solver.SetWeights(Vec<3>::Ones(), Vec<2>(1.0, -2.0));
    ADD_FAILURE() << "negative terminal weight accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("SetWeights: terminal weight 1 must be finite and >= 0"),
              std::string::npos)
        << e.what();
  }
  // and a weight on a row outside the pattern of the last SetWeights (it would need new
  // sparsity patterns, which SetWeightValues does not build)
  solver.SetWeights(Vec<3>(0.0, 1.0, 1.0), Vec<2>::Ones());
  EXPECT_THROW(solver.SetWeightValues(Vec<3>(1.0, 1.0, 1.0), Vec<2>::Ones()),
               std::invalid_argument);
  EXPECT_NO_THROW(solver.SetWeightValues(Vec<3>(0.0, 2.0, 0.0), Vec<2>::Ones()));
  // while the ends of each range are accepted
  EXPECT_NO_THROW(solver.SetReference(4, Vec<3>::Zero()));
  EXPECT_NO_THROW(solver.SetStateBounds(5, lb, ub));
  EXPECT_NO_THROW(solver.SetParameters(0, PointMass::Params{}));
  EXPECT_NO_THROW(solver.SetParameters(5, PointMass::Params{}));
  EXPECT_NO_THROW(solver.SetWeights(Vec<3>(0.0, 1.0, 1.0), Vec<2>::Ones()));
}

TEST(ProblemContractTest, ConstructorRejectsABadStateBoundLayout) {
  // Given a layout with a state index outside 0..nx-1, or soft flags not matching the indices
  // Then construction is refused
  EXPECT_THROW(RtiSolver<PointMass>(PointMass{}, Settings(5, 0.1), StateBoundLayout{{2}, {false}}),
               std::invalid_argument);
  EXPECT_THROW(RtiSolver<PointMass>(PointMass{}, Settings(5, 0.1), StateBoundLayout{{-1}, {false}}),
               std::invalid_argument);
  EXPECT_THROW(RtiSolver<PointMass>(PointMass{}, Settings(5, 0.1), StateBoundLayout{{1}, {}}),
               std::invalid_argument);
  // and a valid soft layout is accepted
  EXPECT_NO_THROW(
      RtiSolver<PointMass>(PointMass{}, Settings(5, 0.1), StateBoundLayout{{1}, {true}}));
}

}  // namespace
}  // namespace fnmpc::rti

// SPDX-License-Identifier: BSD-3-Clause
// The reduced follower with one row block on the mean of n neighbours (n times the weights)
// has the same Gauss-Newton QPs in the inputs as one row block per neighbour, so the same
// iterates: how formation::VehicleController flies any number of neighbours (docs/rti.md).
#include <gtest/gtest.h>

#include <array>
#include <random>

#include "fnmpc/ocp/problems.hpp"
#include "fnmpc/rti/rti_solver.hpp"

namespace fnmpc::rti {
namespace {

constexpr int kN = 3;  // neighbours of the per-neighbour formulation
const Vec3 kWp(20, 20, 30), kWv(2, 2, 2), kBound(6.0, 6.0, 2.0);
constexpr double kTerminal = 5.0;

struct Neighbour {
  Vec3 rel, vel, desired;
};

template <int Nn>
using Solver = RtiSolver<ocp::ReducedFollowerProblem<Nn>>;

// Stage rows: per block j position (3), then velocities (3 per block), phi, theta, T - mg,
// phi_ref, theta_ref. `scale` multiplies the neighbour rows (n for the mean).
template <int Nn>
void Weights(double scale, Solver<Nn>* s) {
  Vec<6 * Nn + 5> w = Vec<6 * Nn + 5>::Zero();
  for (int j = 0; j < Nn; ++j) {
    w.template segment<3>(3 * j) = scale * kWp;
    w.template segment<3>(3 * Nn + 3 * j) = scale * kWv;
  }
  w.template tail<5>() << 1, 1, 0.05, 5, 5;
  s->SetWeights(w, kTerminal * w.template head<6 * Nn + 2>());
}

// Parameters, references and bounds from `blocks` (one per row block); the state bounds
// always from every neighbour in `all`.
template <int Nn>
Vec<9> Setup(const std::array<Neighbour, Nn>& blocks, const std::array<Neighbour, kN>& all,
             const Vec<6>& own, Solver<Nn>* s) {
  using P = ocp::ReducedFollowerProblem<Nn>;
  const double ts = s->settings().sample_time;
  Vec<6 * Nn + 5> y = Vec<6 * Nn + 5>::Zero();
  for (int j = 0; j < Nn; ++j) y.template segment<3>(3 * j) = blocks[j].desired;
  for (int k = 0; k < s->horizon(); ++k) s->SetReference(k, y);
  s->SetTerminalReference(y.template head<6 * Nn + 2>());
  for (int k = 0; k < s->horizon(); ++k)
    s->SetInputBounds(k, Vec3(5, -0.35, -0.35), Vec3(25, 0.35, 0.35));
  Vec<9> lb = Vec<9>::Constant(-kInf), ub = Vec<9>::Constant(kInf);
  for (int k = 0; k <= s->horizon(); ++k) {
    Vec<P::kNp> p;
    p[0] = 0.2;  // psi_ref
    for (int j = 0; j < Nn; ++j) {
      p.template segment<3>(P::ParamRelPos(j)) = blocks[j].rel + (k * ts) * blocks[j].vel;
      p.template segment<3>(P::ParamVel(j)) = blocks[j].vel;
    }
    s->SetParameters(k, p);
    Vec3 lo = Vec3::Constant(-kInf), hi = Vec3::Constant(kInf);
    for (const Neighbour& n : all) {
      const Vec3 c = n.rel + (k * ts) * n.vel;
      lo = lo.cwiseMax(c - kBound);
      hi = hi.cwiseMin(c + kBound);
    }
    if (k >= 1) {
      lb.head<3>() = lo;
      ub.head<3>() = hi;
      s->SetStateBounds(k, lb, ub);
    }
  }
  Vec<9> x0;
  x0 << Vec3::Zero(), own;
  s->InitializeGuess(x0, Vec3(13.4, 0, 0));
  return x0;
}

// Per-neighbour cost of a plan (what the controller logs).
double PerNeighbourCost(const std::vector<Vec<9>>& x, const std::array<Neighbour, kN>& nb,
                        ocp::TargetFrame frame, double ts) {
  double cost = 0.0;
  const int n = static_cast<int>(x.size()) - 1;
  for (int k = 0; k <= n; ++k) {
    const double f = k < n ? 1.0 : kTerminal;
    for (const Neighbour& j : nb) {
      Vec3 r;
      ocp::RelativeRows::Write(frame, Vec3(j.rel + (k * ts) * j.vel - x[k].head<3>()), x[k][8], 1.0,
                               0, 0, 0, &r, static_cast<Mat<3, 9>*>(nullptr));
      cost += 0.5 * f *
              ((r - j.desired).cwiseAbs2().dot(kWp) +
               (j.vel - x[k].segment<3>(3)).cwiseAbs2().dot(kWv));
    }
  }
  return cost;
}

void Compare(ocp::TargetFrame frame, unsigned seed, int* converged) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  RtiSettings settings;
  settings.kkt_threshold = 1e-10;
  settings.max_initial_iterations = 300;
  for (int trial = 0; trial < 5; ++trial) {
    // Given three neighbours around their desired offsets, some near the relative bounds
    std::array<Neighbour, kN> nb;
    for (Neighbour& n : nb) {
      n.desired = Vec3(2.0 * unit(rng), 2.0 * unit(rng), 0.5 * unit(rng));
      n.rel = n.desired + Vec3(unit(rng), unit(rng), 1.9 * unit(rng));
      n.vel = Vec3(0.6 * unit(rng), 0.6 * unit(rng), 0.5 * unit(rng));
    }
    Vec<6> own;
    own << 0.5 * unit(rng), 0.5 * unit(rng), 0.2 * unit(rng), 0.1 * unit(rng), 0.1 * unit(rng),
        0.3 * unit(rng);
    // and their mean with three times the weights
    std::array<Neighbour, 1> mean;
    mean[0] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    for (const Neighbour& n : nb) {
      mean[0].rel += n.rel / kN;
      mean[0].vel += n.vel / kN;
      mean[0].desired += n.desired / kN;
    }
    Solver<kN> per(ocp::ReducedFollowerProblem<kN>{{}, frame}, settings,
                   StateBoundLayout{{0, 1, 2}, {true, true, true}});
    Solver<1> agg(ocp::ReducedFollowerProblem<1>{{}, frame}, settings,
                  StateBoundLayout{{0, 1, 2}, {true, true, true}});
    Weights<kN>(1.0, &per);
    Weights<1>(static_cast<double>(kN), &agg);
    const Vec<9> x0 = Setup<kN>(nb, nb, own, &per);
    Setup<1>(mean, nb, own, &agg);
    // When both iterate to convergence
    Vec3 u_per, u_agg;
    ASSERT_EQ(per.Step(x0, &u_per), RtiStatus::kSuccess);
    ASSERT_EQ(agg.Step(x0, &u_agg), RtiStatus::kSuccess);
    if (!(per.stats().kkt < 1e-8 && agg.stats().kkt < 1e-8)) continue;
    ++*converged;
    // Then the first controls and the plans agree
    EXPECT_LT((u_per - u_agg).lpNorm<Eigen::Infinity>(), 1e-7) << "trial " << trial;
    for (int k = 0; k <= per.horizon(); ++k) {
      EXPECT_LT((per.states()[k] - agg.states()[k]).lpNorm<Eigen::Infinity>(), 1e-7);
    }
    // and the per-neighbour cost is the aggregated one plus the inputs-free spread term
    const double ts = settings.sample_time;
    double spread = 0.0;
    for (int k = 0; k <= agg.horizon(); ++k) {
      const double f = k < agg.horizon() ? 1.0 : kTerminal;
      std::array<Vec3, kN> a;
      Vec3 a_mean = Vec3::Zero();
      for (int j = 0; j < kN; ++j) {
        ocp::RelativeRows::Write(frame, Vec3(nb[j].rel + (k * ts) * nb[j].vel), agg.states()[k][8],
                                 1.0, 0, 0, 0, &a[j], static_cast<Mat<3, 9>*>(nullptr));
        a[j] -= nb[j].desired;
        a_mean += a[j] / kN;
      }
      for (int j = 0; j < kN; ++j) {
        spread +=
            0.5 * f *
            ((a[j] - a_mean).cwiseAbs2().dot(kWp) + (nb[j].vel - mean[0].vel).cwiseAbs2().dot(kWv));
      }
    }
    const double per_cost = PerNeighbourCost(per.states(), nb, frame, ts);
    const std::array<Neighbour, kN> one{mean[0], mean[0], mean[0]};
    const double agg_cost = PerNeighbourCost(agg.states(), one, frame, ts);
    EXPECT_NEAR(per_cost, agg_cost + spread, 1e-8 * per_cost) << "trial " << trial;
    EXPECT_GT(spread, 0.0);
  }
}

TEST(NeighbourMeanTest, SameIteratesAsOneRowBlockPerNeighbour) {
  int converged = 0;
  Compare(ocp::TargetFrame::kInertial, 21, &converged);
  Compare(ocp::TargetFrame::kControl, 22, &converged);
  EXPECT_GE(converged, 8);  // of 10
}

}  // namespace
}  // namespace fnmpc::rti

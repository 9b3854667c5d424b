// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <string_view>
#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/ocp/problems.hpp"
#include "fnmpc/rti/rti_solver.hpp"

/// The fixed benchmark OCPs and closed-loop scenarios of docs/benchmark-spec.md,
/// implemented exactly: problems L, F2, F6 (and the reduced F2, F6 formulations of the
/// same problems), the quintic waypoint references ("nominal", "aggressive").
namespace fnmpc::bench {

enum class Scenario { kNominal, kAggressive };
enum class ProblemId { kL, kF2, kF6, kF2Reduced, kF6Reduced };
std::string_view ToString(Scenario s);
std::string_view ToString(ProblemId p);
inline constexpr std::array<ProblemId, 5> kAllProblems{
    ProblemId::kL, ProblemId::kF2, ProblemId::kF6, ProblemId::kF2Reduced, ProblemId::kF6Reduced};

/// Vehicle of the spec (Table 1 of the reference work).
inline model::AttitudeModelParams SpecVehicle() { return {}; }

/// Solver settings of the spec: Ts = 0.05 s, N = 15, 2 RK4 steps, one SQP iteration per
/// step after an initial convergence to KKT < 1e-6.
rti::RtiSettings SpecSettings();

/// Leader reference: quintic rest-to-rest legs through the six waypoints (nominal: five
/// 4 s legs; aggressive: the tour four times with 1.2 s legs), then hold until 26 s.
class ReferenceTrajectory {
 public:
  explicit ReferenceTrajectory(Scenario scenario);
  /// Position [m] and velocity [m/s] at time t [s].
  void Sample(double t, Vec3* p, Vec3* v) const;
  [[nodiscard]] int num_steps() const { return 520; }  ///< 26 s at Ts = 0.05 s

 private:
  std::vector<Vec3> points_;  // leg k goes from points_[k] to points_[k + 1]
  double leg_duration_ = 4.0;
};

/// Static points of F6's four extra neighbours (world frame).
inline const std::array<Vec3, 4> kF6StaticPoints{Vec3(0.5, 0.5, 1), Vec3(-2.5, 0.5, 1),
                                                 Vec3(0.5, -2.5, 1), Vec3(-2.5, -2.5, 1)};
/// F2 desired offsets of neighbours 1 and 2 (world-aligned).
inline const Vec3 kD1{1, 1, 0};
inline const Vec3 kD2{0, 2, 0};
/// Neighbour 2 flies the reference shifted by this offset.
inline const Vec3 kNeighbour2Shift{-1, 1, 0};
/// Initial follower position.
inline const Vec3 kFollowerStart{-1, -1, 1};

/// What a follower senses of neighbour j at one time: the NeighbourIndex layout.
struct NeighbourState {
  Vec3 rel_pos = Vec3::Zero();  ///< p_j - p_self [m]
  Vec3 vel = Vec3::Zero();      ///< neighbour velocity [m/s]
  double yaw = 0.0;             ///< [rad]
  double yaw_rate = 0.0;        ///< [rad/s]
};

// ---- Problem L ----
using LeaderSolver = rti::RtiSolver<ocp::LeaderProblem>;
/// Builds the spec's L solver (weights, bounds) and its initial guess at rest at x0.
LeaderSolver MakeLeaderSolver(const Vec<9>& x0, const rti::RtiSettings& settings = SpecSettings());
/// Sets the references of every stage for the control step starting at time t.
void SetLeaderReferences(LeaderSolver* solver, const ReferenceTrajectory& ref, double t);

// ---- Problems F2, F6 (full) and their reduced formulations ----
/// Number of neighbours of the benchmark follower problems: 2 or 6.
template <int Nn>
using FollowerSolver = rti::RtiSolver<ocp::FollowerProblem<Nn>>;
template <int Nn>
using ReducedFollowerSolver = rti::RtiSolver<ocp::ReducedFollowerProblem<Nn>>;

/// The spec's follower weights, bounds and references; initial guess from the follower's
/// own (v, phi, theta, psi) and the neighbour states.
template <int Nn>
FollowerSolver<Nn> MakeFollowerSolver(const Vec<6>& own,
                                      const std::array<NeighbourState, Nn>& neighbours,
                                      const rti::RtiSettings& settings = SpecSettings(),
                                      ocp::TargetFrame frame = ocp::TargetFrame::kInertial);
template <int Nn>
ReducedFollowerSolver<Nn> MakeReducedFollowerSolver(
    const Vec<6>& own, const std::array<NeighbourState, Nn>& neighbours,
    const rti::RtiSettings& settings = SpecSettings(),
    ocp::TargetFrame frame = ocp::TargetFrame::kInertial);

/// Full follower state from own (v, angles) and neighbour states.
template <int Nn>
Vec<6 + 8 * Nn> FollowerState(const Vec<6>& own, const std::array<NeighbourState, Nn>& nb);
/// Reduced follower: sets the stage parameters (constant-velocity predictions) and the
/// relative-position bounds mapped onto the displacement; returns x0 = [0, v, angles].
template <int Nn>
Vec<9> SetReducedFollowerStage(ReducedFollowerSolver<Nn>* solver, const Vec<6>& own,
                               const std::array<NeighbourState, Nn>& nb);

/// Desired offsets d_j (zero for F6's static points) and per-neighbour bounds.
template <int Nn>
std::array<Vec3, Nn> DesiredOffsets();
inline const Vec3 kRelPosBound{6.0, 6.0, 2.0};  ///< |dx_j| component bounds [m]

// ---- Closed loop ----
/// One control step of a closed-loop run.
struct StepRecord {
  double step_us = 0;      ///< shift + references + prepare + feedback [us]
  double feedback_us = 0;  ///< x0 to u0 [us]
  int qp_iterations = 0;
  bool unconstrained_step = false;  ///< the unconstrained Riccati step solved the QP
  double kkt = 0;                   ///< KKT value after the step (computed outside the timing)
  double error_m = 0;               ///< L: |p - p_r|; F: mean_j |dx_j - d_j| at the end of the step
  bool fallback = false;
  double input_violation = 0;  ///< largest violation of the input bounds by the applied u
  double hard_state_violation =
      0;  ///< largest violation of the hard state bounds by the QP solution
};

struct ClosedLoopResult {
  ProblemId problem = ProblemId::kL;
  Scenario scenario = Scenario::kNominal;
  std::vector<StepRecord> steps;
  long fallbacks = 0;
  double initial_kkt = 0;      ///< KKT after the initial convergence at t = 0
  int initial_iterations = 0;  ///< SQP iterations of the initial convergence
};

/// Runs the closed-loop scenario of the spec for one problem (plant: the same model,
/// RK4 at 1 ms, no noise, no mismatch). `steps` < 0 runs the whole scenario. Each timed
/// control step (the span of StepRecord::step_us) starts with a call of
/// fnmpc_bench_step_begin and ends with one of fnmpc_bench_step_end.
ClosedLoopResult RunClosedLoop(ProblemId problem, Scenario scenario, int steps = -1,
                               const rti::RtiSettings& settings = SpecSettings());

}  // namespace fnmpc::bench

/// Step markers of RunClosedLoop: empty and never inlined, so that an instruction counter
/// under emulation finds the control steps by these functions' addresses
/// (studies/onboard/onboard-count.py, docs/onboard.md). `step` is the control step's index.
extern "C" void fnmpc_bench_step_begin(int step);
extern "C" void fnmpc_bench_step_end(int step);

namespace fnmpc::bench {

/// Summary figures of a run (medians and maxima over the steps).
struct ClosedLoopSummary {
  double step_median_us = 0, step_p99_us = 0, step_max_us = 0, feedback_median_us = 0;
  double qp_iterations_median = 0, qp_iterations_max = 0;
  double kkt_median = 0, kkt_max = 0, rms_error_m = 0;
  double max_input_violation = 0, max_hard_state_violation = 0;
  long fallbacks = 0;
  long unconstrained_steps = 0;  ///< steps (after step 0) solved by the unconstrained Riccati step
};
ClosedLoopSummary Summarize(const ClosedLoopResult& result);

}  // namespace fnmpc::bench

// The solvers of the benchmark problems are instantiated once, each in its own
// translation unit (solver_instances_*.cpp), to keep compile times down.
namespace fnmpc::rti {
extern template class RtiSolver<ocp::LeaderProblem>;
extern template class RtiSolver<ocp::FollowerProblem<2>>;
extern template class RtiSolver<ocp::FollowerProblem<6>>;
extern template class RtiSolver<ocp::ReducedFollowerProblem<2>>;
extern template class RtiSolver<ocp::ReducedFollowerProblem<6>>;
}  // namespace fnmpc::rti

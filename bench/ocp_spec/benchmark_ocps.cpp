// SPDX-License-Identifier: BSD-3-Clause
#include "bench/ocp_spec/benchmark_ocps.hpp"

#include <algorithm>
#include <cmath>

#include "fnmpc/core/stopwatch.hpp"
#include "fnmpc/model/rk4.hpp"
#include "fnmpc/ocp/quadrotor_ocp.hpp"

namespace fnmpc::bench {

std::string_view ToString(Scenario s) { return s == Scenario::kNominal ? "nominal" : "aggressive"; }

std::string_view ToString(ProblemId p) {
  switch (p) {
    case ProblemId::kL:
      return "L";
    case ProblemId::kF2:
      return "F2";
    case ProblemId::kF6:
      return "F6";
    case ProblemId::kF2Reduced:
      return "F2-reduced";
    case ProblemId::kF6Reduced:
      return "F6-reduced";
  }
  return "?";
}

rti::RtiSettings SpecSettings() {
  rti::RtiSettings s;
  s.horizon = 15;
  s.sample_time = 0.05;
  s.integrator_steps = 2;
  s.kkt_threshold = 1e-6;
  s.max_initial_iterations = 50;
  s.max_iterations = 1;
  return s;
}

ReferenceTrajectory::ReferenceTrajectory(Scenario scenario) {
  const std::array<Vec3, 6> tour{Vec3(0, 0, 1),     Vec3(1.5, 0, 1.5), Vec3(1.5, 1.5, 1),
                                 Vec3(0, 1.5, 1.5), Vec3(-1, 0.75, 1), Vec3(0, 0, 1)};
  const int laps = scenario == Scenario::kNominal ? 1 : 4;
  leg_duration_ = scenario == Scenario::kNominal ? 4.0 : 1.2;
  points_.push_back(tour[0]);
  for (int lap = 0; lap < laps; ++lap) {
    for (std::size_t i = 1; i < tour.size(); ++i) points_.push_back(tour[i]);
  }
}

void ReferenceTrajectory::Sample(double t, Vec3* p, Vec3* v) const {
  const int legs = static_cast<int>(points_.size()) - 1;
  if (t <= 0.0) {
    *p = points_.front();
    v->setZero();
    return;
  }
  const int leg = static_cast<int>(std::floor(t / leg_duration_));
  if (leg >= legs) {
    *p = points_.back();
    v->setZero();
    return;
  }
  const double s = (t - leg * leg_duration_) / leg_duration_;
  const Vec3 delta = points_[leg + 1] - points_[leg];
  const double s3 = s * s * s;
  *p = points_[leg] + delta * (10 * s3 - 15 * s3 * s + 6 * s3 * s * s);
  *v = delta * (30 * s * s - 60 * s3 + 30 * s3 * s) / leg_duration_;
}

namespace {

// The spec's weights and bounds: the defaults of ocp::NmpcWeights (stage 20, 20, 30, 2, 2, 2,
// 1, 1, 0.05, 5, 5; terminal 5 times) and of the controllers' bounds (speed 2 m/s per axis,
// T in [5, 25] N, attitude references within 0.35 rad).
const ocp::NmpcWeights kSpecWeights;
constexpr double kMaxVel = 2.0;
const Vec3 kInputLower(5.0, -0.35, -0.35);
const Vec3 kInputUpper(25.0, 0.35, 0.35);

template <class Solver>
void SetInputBounds(Solver* solver) {
  ocp::quadrotor::SetInputLimits(solver, kInputLower[0], kInputUpper[0], kInputUpper[1]);
}

Vec3 HoverInput() { return {SpecVehicle().mass * kGravity, 0, 0}; }

}  // namespace

LeaderSolver MakeLeaderSolver(const Vec<9>& x0, const rti::RtiSettings& settings) {
  LeaderSolver solver(ocp::LeaderProblem{SpecVehicle()}, settings,
                      ocp::quadrotor::LeaderLayout(/*altitude=*/false, /*soft=*/false));
  solver.SetWeights(ocp::quadrotor::LeaderWeights(kSpecWeights),
                    ocp::quadrotor::LeaderTerminalWeights(kSpecWeights));
  SetInputBounds(&solver);
  Vec<9> lb = Vec<9>::Constant(-kInf), ub = Vec<9>::Constant(kInf);
  ocp::quadrotor::SetSpeedBounds(3, kMaxVel, &lb, &ub);
  for (int k = 1; k <= solver.horizon(); ++k) solver.SetStateBounds(k, lb, ub);
  solver.InitializeGuess(x0, HoverInput());
  return solver;
}

void SetLeaderReferences(LeaderSolver* solver, const ReferenceTrajectory& ref, double t) {
  const double ts = solver->settings().sample_time;
  Vec3 p, v;
  Vec<11> y = Vec<11>::Zero();
  for (int i = 0; i < solver->horizon(); ++i) {
    ref.Sample(t + i * ts, &p, &v);
    y.head<3>() = p;
    y.segment<3>(3) = v;
    solver->SetReference(i, y);
  }
  ref.Sample(t + solver->horizon() * ts, &p, &v);
  Vec<8> yn = Vec<8>::Zero();
  yn.head<3>() = p;
  yn.segment<3>(3) = v;
  solver->SetTerminalReference(yn);
}

template <int Nn>
std::array<Vec3, Nn> DesiredOffsets() {
  std::array<Vec3, Nn> d;
  d.fill(Vec3::Zero());
  d[0] = kD1;
  d[1] = kD2;
  return d;
}

namespace {

// Weights of the spec: neighbours 1 and 2 weighted, the others (F6's static points) not.
template <int Nn, class Solver>
void SetFollowerWeights(Solver* solver) {
  solver->SetWeights(ocp::quadrotor::FollowerWeights<Nn>(kSpecWeights, 2),
                     ocp::quadrotor::FollowerTerminalWeights<Nn>(kSpecWeights, 2));
}

template <int Nn, class Solver>
void FollowerReferences(Solver* solver) {
  Vec<6 * Nn + 5> y = Vec<6 * Nn + 5>::Zero();
  const auto d = DesiredOffsets<Nn>();
  for (int j = 0; j < Nn; ++j) y.template segment<3>(3 * j) = d[j];
  for (int k = 0; k < solver->horizon(); ++k) solver->SetReference(k, y);
  solver->SetTerminalReference(y.template head<6 * Nn + 2>());
}

}  // namespace

template <int Nn>
Vec<6 + 8 * Nn> FollowerState(const Vec<6>& own, const std::array<NeighbourState, Nn>& nb) {
  Vec<6 + 8 * Nn> x;
  x.template head<6>() = own;
  for (int j = 0; j < Nn; ++j) {
    const int o = model::FollowerModel<Nn>::Neighbour(j);
    x.template segment<3>(o) = nb[j].rel_pos;
    x.template segment<3>(o + 3) = nb[j].vel;
    x[o + 6] = nb[j].yaw;
    x[o + 7] = nb[j].yaw_rate;
  }
  return x;
}

template <int Nn>
FollowerSolver<Nn> MakeFollowerSolver(const Vec<6>& own,
                                      const std::array<NeighbourState, Nn>& neighbours,
                                      const rti::RtiSettings& settings, ocp::TargetFrame frame) {
  using Problem = ocp::FollowerProblem<Nn>;
  constexpr int nx = Problem::kNx;
  rti::StateBoundLayout layout{{0, 1, 2}, {false, false, false}};  // own velocity, hard
  Vec<nx> lb = Vec<nx>::Constant(-kInf), ub = Vec<nx>::Constant(kInf);
  ocp::quadrotor::SetSpeedBounds(0, kMaxVel, &lb, &ub);
  for (int j = 0; j < Nn; ++j) {
    const int o = model::FollowerModel<Nn>::Neighbour(j);
    for (int i = 0; i < 3; ++i) {
      layout.indices.push_back(o + i);
      layout.soft.push_back(true);  // relative-position safety bounds are soft by default
      lb[o + i] = -kRelPosBound[i];
      ub[o + i] = kRelPosBound[i];
    }
  }
  FollowerSolver<Nn> solver(Problem{SpecVehicle(), frame}, settings, layout);
  SetFollowerWeights<Nn>(&solver);
  SetInputBounds(&solver);
  for (int k = 1; k <= solver.horizon(); ++k) solver.SetStateBounds(k, lb, ub);
  FollowerReferences<Nn>(&solver);
  solver.InitializeGuess(FollowerState<Nn>(own, neighbours), HoverInput());
  return solver;
}

template <int Nn>
Vec<9> SetReducedFollowerStage(ReducedFollowerSolver<Nn>* solver, const Vec<6>& own,
                               const std::array<NeighbourState, Nn>& nb) {
  using Problem = ocp::ReducedFollowerProblem<Nn>;
  const double ts = solver->settings().sample_time;
  Vec<Problem::kNp> p;
  p[0] = 0.0;  // psi_ref
  for (int j = 0; j < Nn; ++j) p.template segment<3>(Problem::ParamVel(j)) = nb[j].vel;
  Vec<9> lb = Vec<9>::Constant(-kInf), ub = Vec<9>::Constant(kInf);
  ocp::quadrotor::SetSpeedBounds(3, kMaxVel, &lb, &ub);
  for (int k = 0; k <= solver->horizon(); ++k) {
    const double t = k * ts;
    Vec3 s_lo = Vec3::Constant(-kInf), s_hi = Vec3::Constant(kInf);
    for (int j = 0; j < Nn; ++j) {
      const Vec3 c = nb[j].rel_pos + t * nb[j].vel;  // constant-velocity prediction
      p.template segment<3>(Problem::ParamRelPos(j)) = c;
      ocp::quadrotor::IntersectRelativeBound(c, kRelPosBound, &s_lo, &s_hi);
    }
    solver->SetParameters(k, p);
    if (k >= 1) {
      lb.head<3>() = s_lo;
      ub.head<3>() = s_hi;
      solver->SetStateBounds(k, lb, ub);
    }
  }
  Vec<9> x0;
  x0.head<3>().setZero();
  x0.tail<6>() = own;
  return x0;
}

template <int Nn>
ReducedFollowerSolver<Nn> MakeReducedFollowerSolver(
    const Vec<6>& own, const std::array<NeighbourState, Nn>& neighbours,
    const rti::RtiSettings& settings, ocp::TargetFrame frame) {
  using Problem = ocp::ReducedFollowerProblem<Nn>;
  ReducedFollowerSolver<Nn> solver(Problem{SpecVehicle(), frame}, settings,
                                   ocp::quadrotor::ReducedFollowerLayout(/*soft_velocity=*/false));
  SetFollowerWeights<Nn>(&solver);
  SetInputBounds(&solver);
  FollowerReferences<Nn>(&solver);
  const Vec<9> x0 = SetReducedFollowerStage<Nn>(&solver, own, neighbours);
  solver.InitializeGuess(x0, HoverInput());
  return solver;
}

#define FNMPC_INSTANTIATE(NN)                                                                    \
  template std::array<Vec3, NN> DesiredOffsets<NN>();                                            \
  template Vec<6 + 8 * NN> FollowerState<NN>(const Vec<6>&,                                      \
                                             const std::array<NeighbourState, NN>&);             \
  template FollowerSolver<NN> MakeFollowerSolver<NN>(const Vec<6>&,                              \
                                                     const std::array<NeighbourState, NN>&,      \
                                                     const rti::RtiSettings&, ocp::TargetFrame); \
  template ReducedFollowerSolver<NN> MakeReducedFollowerSolver<NN>(                              \
      const Vec<6>&, const std::array<NeighbourState, NN>&, const rti::RtiSettings&,             \
      ocp::TargetFrame);                                                                         \
  template Vec<9> SetReducedFollowerStage<NN>(ReducedFollowerSolver<NN>*, const Vec<6>&,         \
                                              const std::array<NeighbourState, NN>&);
FNMPC_INSTANTIATE(2)
FNMPC_INSTANTIATE(6)
#undef FNMPC_INSTANTIATE

// ---- Closed loop ----

}  // namespace fnmpc::bench

// The empty asm keeps each call: the compiler may not drop a call of an empty function.
extern "C" [[gnu::noinline]] void fnmpc_bench_step_begin(int step) { asm volatile("" ::"r"(step)); }
extern "C" [[gnu::noinline]] void fnmpc_bench_step_end(int step) { asm volatile("" ::"r"(step)); }

namespace fnmpc::bench {

namespace {

// Plant: the same quadrotor model, RK4 at 1 ms for one sampling time.
Vec<9> PlantStep(const Vec<9>& x, const Vec3& u, double ts) {
  Vec<9> out = x;
  const int n = static_cast<int>(std::lround(ts / 1e-3));
  for (int i = 0; i < n; ++i) {
    out = model::Rk4<model::QuadrotorModel>(out, u, 0.0, SpecVehicle(), 1e-3, 1);
  }
  return out;
}

double InputViolation(const Vec3& u) {
  return std::max((kInputLower - u).maxCoeff(), (u - kInputUpper).maxCoeff());
}

template <class Solver>
double HardStateViolation(const Solver& solver) {
  double worst = -kInf;
  const auto& layout = solver.layout();
  for (int k = 1; k <= solver.horizon(); ++k) {
    for (std::size_t c = 0; c < layout.indices.size(); ++c) {
      if (layout.soft[c]) continue;
      const int i = layout.indices[c];
      const double v = solver.states()[k][i];
      worst =
          std::max({worst, solver.lower_state_bound(k)[i] - v, v - solver.upper_state_bound(k)[i]});
    }
  }
  return worst;
}

template <class Solver>
void Record(Solver* solver, const Vec<Solver::kNx>& x0, const Vec3& u, const Stopwatch& sw,
            ClosedLoopResult* result, StepRecord* rec) {
  rec->step_us = 1e6 * sw.Seconds();
  rec->feedback_us = 1e6 * solver->stats().time_feedback;
  rec->qp_iterations = solver->stats().qp_iterations;
  rec->unconstrained_step = solver->stats().unconstrained_step;
  rec->fallback = solver->stats().fallback;
  rec->kkt = solver->ComputeKkt(x0);
  rec->input_violation = InputViolation(u);
  rec->hard_state_violation = HardStateViolation(*solver);
  result->fallbacks = solver->stats().fallback_count;
}

ClosedLoopResult RunLeader(Scenario scenario, int steps, const rti::RtiSettings& settings) {
  ClosedLoopResult result;
  const ReferenceTrajectory ref(scenario);
  Vec<9> x = Vec<9>::Zero();
  x[2] = 1.0;
  LeaderSolver solver = MakeLeaderSolver(x, settings);
  const double ts = settings.sample_time;
  Vec3 u, p, v;
  for (int k = 0; k < steps; ++k) {
    const double t = k * ts;
    StepRecord rec;
    Stopwatch sw;
    fnmpc_bench_step_begin(k);
    if (k > 0) solver.Shift();
    SetLeaderReferences(&solver, ref, t);
    solver.Step(x, &u);
    fnmpc_bench_step_end(k);
    Record(&solver, x, u, sw, &result, &rec);
    if (k == 0) {
      result.initial_iterations = solver.stats().sqp_iterations;
      result.initial_kkt = rec.kkt;
    }
    x = PlantStep(x, u, ts);
    ref.Sample(t + ts, &p, &v);
    rec.error_m = (x.head<3>() - p).norm();
    result.steps.push_back(rec);
  }
  return result;
}

template <int Nn>
std::array<NeighbourState, Nn> SenseNeighbours(const ReferenceTrajectory& ref, double t,
                                               const Vec3& p_self) {
  std::array<NeighbourState, Nn> nb;
  Vec3 p, v;
  ref.Sample(t, &p, &v);
  nb[0] = {p - p_self, v, 0.0, 0.0};
  nb[1] = {p + kNeighbour2Shift - p_self, v, 0.0, 0.0};
  for (int j = 2; j < Nn; ++j) nb[j] = {kF6StaticPoints[j - 2] - p_self, Vec3::Zero(), 0, 0};
  return nb;
}

template <int Nn, bool kReduced>
ClosedLoopResult RunFollower(Scenario scenario, int steps, const rti::RtiSettings& settings) {
  ClosedLoopResult result;
  const ReferenceTrajectory ref(scenario);
  Vec<9> plant = Vec<9>::Zero();  // follower: p, v, angles
  plant.head<3>() = kFollowerStart;
  const double ts = settings.sample_time;
  auto nb = SenseNeighbours<Nn>(ref, 0.0, plant.head<3>());
  Vec<6> own = plant.tail<6>();
  using Solver = std::conditional_t<kReduced, ReducedFollowerSolver<Nn>, FollowerSolver<Nn>>;
  Solver solver = [&] {
    if constexpr (kReduced) {
      return MakeReducedFollowerSolver<Nn>(own, nb, settings);
    } else {
      return MakeFollowerSolver<Nn>(own, nb, settings);
    }
  }();
  Vec3 u;
  const auto d = DesiredOffsets<Nn>();
  for (int k = 0; k < steps; ++k) {
    const double t = k * ts;
    nb = SenseNeighbours<Nn>(ref, t, plant.head<3>());
    own = plant.tail<6>();
    StepRecord rec;
    Stopwatch sw;
    fnmpc_bench_step_begin(k);
    Vec<Solver::kNx> x0;
    if constexpr (kReduced) {
      if (k > 0) {
        solver.Shift();
        Vec<9> shift = Vec<9>::Zero();
        shift.head<3>() = -solver.states()[0].template head<3>();
        solver.OffsetGuess(shift);  // the displacement restarts at zero
      }
      x0 = SetReducedFollowerStage<Nn>(&solver, own, nb);
    } else {
      if (k > 0) solver.Shift();
      x0 = FollowerState<Nn>(own, nb);
    }
    solver.Step(x0, &u);
    fnmpc_bench_step_end(k);
    Record(&solver, x0, u, sw, &result, &rec);
    if (k == 0) {
      result.initial_iterations = solver.stats().sqp_iterations;
      result.initial_kkt = rec.kkt;
    }
    plant = PlantStep(plant, u, ts);
    const auto after = SenseNeighbours<Nn>(ref, t + ts, plant.head<3>());
    rec.error_m = 0.5 * ((after[0].rel_pos - d[0]).norm() + (after[1].rel_pos - d[1]).norm());
    result.steps.push_back(rec);
  }
  return result;
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto idx = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())) - 1);
  return v[std::min(idx, v.size() - 1)];
}

}  // namespace

ClosedLoopResult RunClosedLoop(ProblemId problem, Scenario scenario, int steps,
                               const rti::RtiSettings& settings) {
  if (steps < 0) steps = ReferenceTrajectory(scenario).num_steps();
  ClosedLoopResult r;
  switch (problem) {
    case ProblemId::kL:
      r = RunLeader(scenario, steps, settings);
      break;
    case ProblemId::kF2:
      r = RunFollower<2, false>(scenario, steps, settings);
      break;
    case ProblemId::kF6:
      r = RunFollower<6, false>(scenario, steps, settings);
      break;
    case ProblemId::kF2Reduced:
      r = RunFollower<2, true>(scenario, steps, settings);
      break;
    case ProblemId::kF6Reduced:
      r = RunFollower<6, true>(scenario, steps, settings);
      break;
  }
  r.problem = problem;
  r.scenario = scenario;
  return r;
}

ClosedLoopSummary Summarize(const ClosedLoopResult& result) {
  ClosedLoopSummary s;
  std::vector<double> step, fb, qpit, kkt;
  double sq = 0.0;
  for (std::size_t k = 0; k < result.steps.size(); ++k) {
    const StepRecord& r = result.steps[k];
    // Step 0 carries the initial convergence (many SQP iterations): reported apart.
    if (k > 0) {
      step.push_back(r.step_us);
      fb.push_back(r.feedback_us);
      qpit.push_back(r.qp_iterations);
      s.unconstrained_steps += r.unconstrained_step ? 1 : 0;
    }
    kkt.push_back(r.kkt);
    sq += r.error_m * r.error_m;
    s.max_input_violation = std::max(s.max_input_violation, r.input_violation);
    s.max_hard_state_violation = std::max(s.max_hard_state_violation, r.hard_state_violation);
  }
  s.step_median_us = Percentile(step, 0.5);
  s.step_p99_us = Percentile(step, 0.99);
  s.step_max_us = Percentile(step, 1.0);
  s.feedback_median_us = Percentile(fb, 0.5);
  s.qp_iterations_median = Percentile(qpit, 0.5);
  s.qp_iterations_max = Percentile(qpit, 1.0);
  s.kkt_median = Percentile(kkt, 0.5);
  s.kkt_max = Percentile(kkt, 1.0);
  s.rms_error_m =
      result.steps.empty() ? 0.0 : std::sqrt(sq / static_cast<double>(result.steps.size()));
  s.fallbacks = result.fallbacks;
  return s;
}

}  // namespace fnmpc::bench

// SPDX-License-Identifier: BSD-3-Clause
// NMPC cores of the vehicle controller. The solvers (leader, reduced follower) are
// instantiated implicitly in this translation unit.
#include "fnmpc/formation/nmpc_core.hpp"

#include <algorithm>
#include <cmath>

#include "fnmpc/formation/neighbour_acceleration.hpp"
#include "fnmpc/formation/throttle_map.hpp"
#include "fnmpc/ocp/problem_extensions.hpp"
#include "fnmpc/ocp/quadrotor_ocp.hpp"
#include "fnmpc/ocp/wake_extension.hpp"

namespace fnmpc::formation {

WakeSlots WakeSources(const std::array<bool, kMaxNeighbours>& active, int count) {
  WakeSlots source;
  source.fill(-1);
  for (int j = 0, o = 0; j < count && o < kWakeSlots; ++j) {
    if (active[j]) source[o++] = j;
  }
  return source;
}

ThrustEstimate NeighbourThrust(const ControllerConfig& c, const Vec3& acc) {
  return ThrustFromAcceleration(c.params.mass, acc, std::max(c.thrust_max, c.pid.max_thrust));
}

Vec3 ObstacleAt(const NmpcInput& in, int o, double t) {
  const Vec3& s = in.obstacle_spread[o];
  const double margin = std::sqrt(std::max(0.0, s[0] + 2.0 * t * s[1] + t * t * s[2]));
  return in.obstacle_rel[o] + t * in.obstacle_vel[o] - margin * in.obstacle_normal[o];
}

namespace {

template <class Solver, class Problem>
double Objective(const Solver& s, const Problem& problem, const typename Solver::Y& w,
                 const typename Solver::YN& wn, const std::vector<typename Solver::Y>& yref,
                 const typename Solver::YN& yref_n, const std::vector<typename Solver::P>& params) {
  double cost = 0.0;
  typename Solver::Y y;
  for (int k = 0; k < s.horizon(); ++k) {
    problem.StageResidual(s.states()[k], s.inputs()[k], params[k], &y, nullptr, nullptr);
    cost += 0.5 * (y - yref[k]).cwiseAbs2().dot(w);
  }
  typename Solver::YN yn;
  problem.TerminalResidual(s.states()[s.horizon()], params[s.horizon()], &yn, nullptr);
  cost += 0.5 * (yn - yref_n).cwiseAbs2().dot(wn);
  return cost;
}

// The solver's current iterate into a plan: positions as displacements from the first stage
// (a follower's states are displacements already, a leader's are absolute), velocities, and
// the thrust input of each interval (the last interval's at the terminal point).
template <class Solver>
void WritePlan(const Solver& s, PlanMessage* out) {
  const int n = std::min(s.horizon(), kMaxPlanIntervals);
  out->points = n + 1;
  const Vec3 origin = s.states()[0].template head<3>();
  for (int k = 0; k <= n; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const auto& x = s.states()[i];
    out->displacement[i] = x.template head<3>() - origin;
    out->velocity[i] = x.template segment<3>(3);
    out->thrust[i] = s.inputs()[static_cast<std::size_t>(std::min(k, s.horizon() - 1))][0];
  }
}

// One RTI step from x0 into *out; a forced failure (fault injection) does what Algorithm 1
// does on a solver error, without solving: the iterate stays the time-shifted previous
// solution and its first control is applied.
template <class Solver>
void SolveStep(Solver* s, const typename Solver::X& x0, bool forced_failure, NmpcStep* out) {
  if (forced_failure) {
    out->u = s->inputs()[0];
    out->stats = s->stats();
    out->stats.fallback = true;
    out->stats.sqp_iterations = 0;
    out->stats.qp_iterations = 0;
    out->stats.time_prepare = 0.0;
    out->stats.time_feedback = 0.0;
    out->stats.time_total = 0.0;
    return;
  }
  s->Step(x0, &out->u);
  out->stats = s->stats();
}

// Offset-free steady-state target (Compensation::kObserver): the model's hover under the
// external acceleration d, v' = BodyZ(phi, theta, psi) T / m - g e3 + d = 0 at the yaw psi,
// i.e. thrust m |g e3 - d| along g e3 - d, the attitude it needs and the references that hold
// it (angle = k ref). Written into the rows every stage residual of both cores shares after
// the position and velocity rows: phi, theta (6, 7), T - m g (8), phi_ref, theta_ref (9, 10);
// terminal rows phi, theta (6, 7). Without it the input rows would pull the inputs back to the
// undisturbed hover and leave an offset. (Maeder, Borrelli, Morari, "Linear offset-free model
// predictive control", Automatica 45 (2009): the target follows the disturbance estimate.)
struct HoverTarget {
  double phi = 0.0, theta = 0.0, thrust = 0.0, phi_ref = 0.0, theta_ref = 0.0;
  HoverTarget(const Vec3& d, double psi, const model::AttitudeModelParams& m) {
    const Vec3 a = Vec3(0.0, 0.0, kGravity) - d;  // specific thrust the hover needs
    const double c = std::cos(psi), s = std::sin(psi);
    const Vec3 ac(c * a.x() + s * a.y(), -s * a.x() + c * a.y(), a.z());  // yaw frame
    const double n = a.norm();
    // BodyZ in the yaw frame is (sin theta cos phi, -sin phi, cos theta cos phi).
    phi = std::asin(std::clamp(-ac.y() / n, -1.0, 1.0));
    theta = std::atan2(ac.x(), ac.z());
    thrust = m.mass * n;
    phi_ref = phi / m.gain[0];
    theta_ref = theta / m.gain[1];
  }
  template <class Y>
  void WriteStage(Y* y, double mass) const {
    (*y)[6] = phi;
    (*y)[7] = theta;
    (*y)[8] = thrust - mass * kGravity;
    (*y)[9] = phi_ref;
    (*y)[10] = theta_ref;
  }
  template <class Y>
  void WriteTerminal(Y* y) const {
    (*y)[6] = phi;
    (*y)[7] = theta;
  }
};

// The controller's input bounds; o: the attitude offset's reference correction (the
// controller sends u - o, AttitudeOffset), which moves the attitude bounds to
// [-max + o, max + o] so that the reference sent stays within +-max_attitude_ref unclamped.
template <class Solver>
void InputBounds(const ControllerConfig& c, Solver* s, const Vec<2>& o = Vec<2>::Zero()) {
  ocp::quadrotor::SetInputLimits(s, c.thrust_min, c.thrust_max, c.max_attitude_ref, o);
}

// Bounds of the leader's position z and velocity, of the follower's displacement and
// velocity: soft (exact-penalty slacks), so that no state can make a QP infeasible; the
// input bounds stay hard.
class LeaderCore final : public NmpcCore {
 public:
  using Base = ocp::WithObstacles<ocp::LeaderProblem, kObstacleSlots>;
  using Problem = ocp::WithAcceleration<ocp::WithInputRate<Base>>;
  using Solver = rti::RtiSolver<Problem>;
  explicit LeaderCore(const ControllerConfig& c)
      : c_(c),
        solver_(Problem(ocp::WithInputRate<Base>(
                    Base(ocp::LeaderProblem{model::AttitudeModelParams::From(c.params)},
                         c.safety.collision_radius))),
                c.rti, ocp::quadrotor::LeaderLayout(/*altitude=*/true, /*soft=*/true)) {
    const NmpcWeights& wt = c.weights;
    w_.setZero();
    w_.head<11>() = ocp::quadrotor::LeaderWeights(wt);
    w_.segment<kObstacleSlots>(11).setConstant(wt.collision);
    w_.tail<3>() << wt.thrust_rate, wt.attitude_ref_rate, wt.attitude_ref_rate;
    wn_.head<8>() = ocp::quadrotor::LeaderTerminalWeights(wt);
    wn_.tail<kObstacleSlots>().setConstant(wt.collision);
    solver_.SetWeights(w_, wn_);
    InputBounds(c, &solver_);
    Solver::X lb = Solver::X::Constant(-kInf), ub = Solver::X::Constant(kInf);
    lb[2] = c.safety.min_altitude;  // z of the CoM, the ground plane at z = 0
    ub[2] = c.safety.max_altitude;
    ocp::quadrotor::SetSpeedBounds(3, c.max_speed, &lb, &ub);
    for (int k = 1; k <= solver_.horizon(); ++k) solver_.SetStateBounds(k, lb, ub);
    yref_.assign(solver_.horizon(), Solver::Y::Zero());
    params_.assign(solver_.horizon() + 1, Solver::P::Zero());
    yref_n_.setZero();
  }

  void Engage(const Vec3& anchor, double yaw_ref) override {
    anchor_ = anchor;
    yaw_ref_ = yaw_ref;
  }

  void ShiftAttitudeBounds(const Vec<2>& o) override { InputBounds(c_, &solver_, o); }

  void Start(const NmpcInput& in, const Vec3& u_guess) override {
    solver_.InitializeGuess(State(in), u_guess);
    first_ = true;
  }

  NmpcStep Step(const NmpcInput& in) override {
    NmpcStep out;
    if (!first_) solver_.Shift();
    first_ = false;
    References(in);
    Obstacles(in);
    x0_ = State(in);
    SolveStep(&solver_, x0_, in.forced_failure, &out);
    out.reference = yref_[0].head<3>();
    return out;
  }

  void Diagnose(double* kkt, double* cost) override {
    *kkt = solver_.ComputeKkt(x0_);
    *cost = Objective(solver_, solver_.problem(), w_, wn_, yref_, yref_n_, params_);
  }

  void Predicted(const Vec3& /*origin*/, std::vector<Vec3>* out) const override {
    for (const auto& x : solver_.states()) out->push_back(x.template head<3>());
  }

  void Plan(PlanMessage* out) const override { WritePlan(solver_, out); }

 private:
  static Solver::X State(const NmpcInput& in) {
    Solver::X x;
    x << in.position, in.own, in.last_command;
    return x;
  }
  // Obstacles in {n}: own position plus the constant-velocity prediction of each.
  void Obstacles(const NmpcInput& in) {
    const double ts = c_.rti.sample_time;
    for (int k = 0; k <= solver_.horizon(); ++k) {
      Solver::P& p = params_[k];
      p[0] = yaw_ref_;
      p.segment<3>(Problem::kParamAcceleration) = in.disturbance;
      for (int o = 0; o < kObstacleSlots; ++o) {
        if (o >= in.obstacles) {
          Base::SetUnused(o, &p);
          continue;
        }
        p.segment<3>(Base::ParamObstacle(o)) = in.position + ObstacleAt(in, o, k * ts);
        p.segment<3>(Base::ParamNormal(o)) = in.obstacle_normal[o];
      }
      solver_.SetParameters(k, p);
    }
  }
  void References(const NmpcInput& in) {
    const double ts = c_.rti.sample_time;
    const bool target = c_.compensation >= Compensation::kObserver;
    const HoverTarget hover(in.disturbance, yaw_ref_, solver_.problem().base.params);
    Vec3 p, v;
    for (int k = 0; k <= solver_.horizon(); ++k) {
      c_.trajectory.Sample(in.t + k * ts - c_.trajectory_start, &p, &v);
      if (k < solver_.horizon()) {
        yref_[k].setZero();
        yref_[k].head<3>() = anchor_ + p;
        yref_[k].segment<3>(3) = v;
        if (target) hover.WriteStage(&yref_[k], c_.params.mass);
        solver_.SetReference(k, yref_[k]);
      } else {
        yref_n_.setZero();
        yref_n_.head<3>() = anchor_ + p;
        yref_n_.segment<3>(3) = v;
        if (target) hover.WriteTerminal(&yref_n_);
        solver_.SetTerminalReference(yref_n_);
      }
    }
  }

  ControllerConfig c_;
  Vec3 anchor_ = Vec3::Zero();
  double yaw_ref_ = 0.0;
  Solver solver_;
  Solver::Y w_;
  Solver::YN wn_;
  std::vector<Solver::Y> yref_;
  Solver::YN yref_n_;
  std::vector<Solver::P> params_;
  Solver::X x0_ = Solver::X::Zero();
  bool first_ = true;
};

// Any number of formation neighbours with one set of residual rows: for a diagonal weight W
// shared by the neighbours, sum_j |a_j - x|_W^2 = n |a_mean - x|_W^2 + sum_j |a_j - a_mean|_W^2,
// with a_j = the neighbour's predicted relative position (rotated into {c} for frame c) minus
// its desired offset, and x the own displacement (likewise for the velocities). The last sum
// does not depend on the inputs (the yaw is not steered by them), so the reduced problem with
// one neighbour, the mean of the active neighbours as its target and n times the weights has
// the same Gauss-Newton QP in the inputs as one with a row block per neighbour
// (tests/rti/neighbour_mean_test.cpp). Diagnose() adds the spread term back to the cost.
// With tie weights w_j (ControllerSettings::tie_weights, summing to n) the same holds for
// the weighted sum: sum_j w_j |a_j - x|_W^2 = n |a_w - x|_W^2 + sum_j w_j |a_j - a_w|_W^2,
// a_w = sum_j w_j a_j / n; equal weights (w_j = 1) are the plain mean.
class FollowerCore final : public NmpcCore {
 public:
  using Reduced = ocp::ReducedFollowerProblem<1>;
  using Base = ocp::WithObstacles<Reduced, kObstacleSlots>;
  using Wake = ocp::WithWake<ocp::WithInputRate<Base>, kWakeSlots>;
  using Problem = ocp::WithAcceleration<Wake>;
  using Solver = rti::RtiSolver<Problem>;
  using X = Solver::X;
  static constexpr int kNyR = Reduced::kNy, kNyNR = Reduced::kNyN;
  explicit FollowerCore(const ControllerConfig& c)
      : c_(c),
        solver_(Problem(Wake(ocp::WithInputRate<Base>(
                                 Base(Reduced{model::AttitudeModelParams::From(c.params), c.frame},
                                      c.safety.collision_radius)),
                             model::WakeForceModel(c.params))),
                c.rti, ocp::quadrotor::ReducedFollowerLayout(/*soft_velocity=*/true)) {
    const NmpcWeights& wt = c.weights;
    w_.setZero();
    w_.head<kNyR>() = ocp::quadrotor::FollowerWeights<1>(wt);
    w_.segment<kObstacleSlots>(kNyR).setConstant(wt.collision);
    w_.tail<3>() << wt.thrust_rate, wt.attitude_ref_rate, wt.attitude_ref_rate;
    TerminalWeights(w_, &wn_);
    solver_.SetWeights(w_, wn_);
    InputBounds(c, &solver_);
    nn_ = static_cast<int>(c.neighbours.size());
    for (int j = 0; j < nn_; ++j) {
      desired_[j] = c.neighbours[j].desired;
      depth_[j] = c.neighbours[j].depth;
    }
    yref_.assign(solver_.horizon(), Solver::Y::Zero());
    yref_n_.setZero();
    params_.assign(solver_.horizon() + 1, Solver::P::Zero());
    active_.fill(false);
    for (int j = 0; j < nn_; ++j) active_[j] = true;
    for (Vec3& e : disagreement_) e.setZero();
    Aggregate();
  }

  void Engage(const Vec3& /*anchor*/, double yaw_ref) override { yaw_ref_ = yaw_ref; }

  void ShiftAttitudeBounds(const Vec<2>& o) override { InputBounds(c_, &solver_, o); }

  void Start(const NmpcInput& in, const Vec3& u_guess) override {
    ActiveNeighbours(in);
    ShareTies(in);
    solver_.InitializeGuess(Stage(in), u_guess);
    first_ = true;
  }

  NmpcStep Step(const NmpcInput& in) override {
    NmpcStep out;
    if (!first_) {
      solver_.Shift();
      X shift = X::Zero();
      shift.head<3>() = -solver_.states()[0].head<3>();
      solver_.OffsetGuess(shift);  // the displacement restarts at zero every step
    }
    first_ = false;
    ActiveNeighbours(in);
    ShareTies(in);
    // The hover target under the whole predicted push now: d and the wake model's part.
    if (c_.compensation >= Compensation::kObserver) Targets(in.disturbance + in.wake);
    x0_ = Stage(in);
    SolveStep(&solver_, x0_, in.forced_failure, &out);
    return out;
  }

  void Diagnose(double* kkt, double* cost) override {
    *kkt = solver_.ComputeKkt(x0_);
    *cost = Objective(solver_, solver_.problem(), w_active_, wn_active_, yref_, yref_n_, params_) +
            SpreadCost();
  }

  void Predicted(const Vec3& origin, std::vector<Vec3>* out) const override {
    for (const auto& x : solver_.states()) out->push_back(origin + x.head<3>());
  }

  void Plan(PlanMessage* out) const override { WritePlan(solver_, out); }

 private:
  // Terminal: the reduced follower's rows times terminal_factor, the obstacle rows as is.
  void TerminalWeights(const Solver::Y& w, Solver::YN* wn) const {
    wn->head<kNyNR>() = c_.weights.terminal_factor * w.head<kNyNR>();
    wn->tail<kObstacleSlots>() = w.segment<kObstacleSlots>(kNyR);
  }

  // The active neighbours' tie-weighted mean desired offset as the reference, n times the
  // weights (a lost neighbour leaves the mean and the tie weights are shared anew; with none
  // the rows get weight zero, the pattern is kept: no allocation).
  void Aggregate() {
    int n = 0;
    TieWeights(c_.tie_weights, depth_.data(), active_.data(), nn_, rule_tie_.data());
    tie_ = rule_tie_;
    for (int j = 0; j < nn_; ++j) n += active_[j] ? 1 : 0;
    active_count_ = n;
    w_active_ = w_;
    w_active_.head<6>() *= static_cast<double>(n);
    TerminalWeights(w_active_, &wn_active_);
    solver_.SetWeightValues(w_active_, wn_active_);
    TieReference();
  }

  // The tie-weighted mean desired offset as every stage's reference.
  void TieReference() {
    Vec3 d = Vec3::Zero();
    for (int j = 0; j < nn_; ++j) {
      if (active_[j]) d += tie_[j] * desired_[j];
    }
    if (active_count_ > 0) d /= active_count_;
    for (int k = 0; k < solver_.horizon(); ++k) {
      yref_[k].head<3>() = d;
      solver_.SetReference(k, yref_[k]);
    }
    yref_n_.head<3>() = d;
    solver_.SetTerminalReference(yref_n_);
  }

  // The hover target under d in the input and attitude rows of every stage (HoverTarget).
  void Targets(const Vec3& d) {
    const HoverTarget hover(d, yaw_ref_, solver_.problem().base.base.params);
    for (int k = 0; k < solver_.horizon(); ++k) {
      hover.WriteStage(&yref_[k], c_.params.mass);
      solver_.SetReference(k, yref_[k]);
    }
    hover.WriteTerminal(&yref_n_);
    solver_.SetTerminalReference(yref_n_);
  }

  void ActiveNeighbours(const NmpcInput& in) {
    bool changed = false;
    for (int j = 0; j < nn_; ++j) {
      changed = changed || in.active[j] != active_[j];
      active_[j] = in.active[j];
    }
    if (changed) Aggregate();
  }

  // The rule's weights discounted by each tie's disagreement with the ties towards the leader
  // (ControllerSettings::tie_disagreement), from the current estimates: the place tie j asks
  // for is the neighbour's relative position (in the frame of the desired offsets) minus its
  // desired offset, as in SpreadCost. The disagreement also widens that neighbour's
  // relative-position bound (Stage): the bound would otherwise drag the follower after a
  // neighbour leaving sideways (triangle, follower2 killed, reality on, seed 4: follower1
  // pulled 0.9 m by its 4 m bound to follower2 drifting 2.2 m).
  void ShareTies(const NmpcInput& in) {
    if (!(c_.tie_disagreement > 0.0) || active_count_ < 2) {
      for (Vec3& e : disagreement_) e.setZero();
      discounted_ = false;  // Aggregate wrote the references of the undiscounted weights
      return;
    }
    const double psi = in.own[5];
    std::array<Vec3, kMaxNeighbours> place{};
    for (int j = 0; j < nn_; ++j) {
      if (!active_[j]) continue;
      ocp::RelativeRows::Write(c_.frame, in.neighbours[j].rel_pos, psi, 1.0, 0, 0, 0, &place[j],
                               static_cast<Mat<3, 9>*>(nullptr));
      place[j] -= desired_[j];
    }
    tie_ = rule_tie_;
    // The references change only with the weights: written when a weight is discounted now or
    // was last step (an unknown depth or one depth only: never).
    const bool discounted =
        DiscountDisagreeingTies(depth_.data(), active_.data(), place.data(), c_.tie_disagreement,
                                nn_, tie_.data(), disagreement_.data());
    if (discounted || discounted_) TieReference();
    discounted_ = discounted;
  }

  // Neighbour j's prediction at stage k (relative position and velocity): constant velocity,
  // or with its estimated acceleration decaying (neighbour_acceleration_decay > 0), held on
  // the ground: no neighbour is below its resting height (relative z floor_), where
  // it stops. Without the floor a falling neighbour's prediction went metres below the
  // ground within the horizon (and its estimate too, once the filter gated the measurements
  // of the stopped vehicle), its relative-position bound then conflicted with the altitude
  // bound (equal penalties) and the cost broke the tie downwards: both followers of fault
  // campaign run 55 followed their falling leader into the ground at 2.3 m/s.
  // Cooperative mode: neighbour j's fresh plan instead (NeighbourPlans::Predict: anchored at
  // rel_[j] and vel_[j], shifted by the plan's age), with its planned thrust in *thrust.
  void Predict(int j, int k, Vec3* rel, Vec3* vel, double* thrust = nullptr) const {
    PlanPrediction plan;
    if (plans_ != nullptr &&
        plans_->Predict(j, t_, k * c_.rti.sample_time, c_.plan_timeout, rel_[j], vel_[j], &plan)) {
      *rel = plan.rel;
      *vel = plan.vel;
      if (thrust != nullptr) *thrust = plan.thrust;
    } else {
      DecayingAccelerationPrediction(rel_[j], vel_[j], acc_[j], c_.neighbour_acceleration_decay,
                                     k * c_.rti.sample_time, rel, vel);
      if (thrust != nullptr) *thrust = thrust_[j];
    }
    if (rel->z() < floor_) {
      rel->z() = floor_;
      vel->z() = 0.0;
    }
  }

  // Stage parameters from the neighbours' constant-velocity predictions (their mean over the
  // active ones; Predict), relative-position bounds mapped onto the displacement s:
  // -b <= c_j - s <= b for every active j (cf. SetReducedFollowerStage), the altitude bounds
  // onto s_z from the current height, the obstacles' predictions.
  X Stage(const NmpcInput& in) {
    const double ts = c_.rti.sample_time;
    X lb = X::Constant(-kInf), ub = X::Constant(kInf);
    ocp::quadrotor::SetSpeedBounds(3, c_.max_speed, &lb, &ub);
    const Vec3& b = c_.relative_position_bound;
    const bool height_known = std::isfinite(in.height);
    floor_ = height_known ? c_.ground_height - in.height : -kInf;
    for (int j = 0; j < nn_; ++j) {
      rel_[j] = in.neighbours[j].rel_pos;
      vel_[j] = in.neighbours[j].vel;
      acc_[j] = in.neighbours[j].acc;
      thrust_[j] = in.neighbours[j].thrust;
    }
    plans_ = in.plans;
    t_ = in.t;
    // Compensation::kWake: the wakes of WakeSources at their predictions (Predict) and
    // NeighbourThrust (cooperative: the planned thrust); d is then the estimator's rest beyond
    // the model (NmpcInput).
    WakeSlots source;
    source.fill(-1);
    if (c_.compensation >= Compensation::kWake) source = WakeSources(active_, nn_);
    for (int k = 0; k <= solver_.horizon(); ++k) {
      Solver::P& p = params_[k];
      p[0] = yaw_ref_;
      for (int o = 0; o < kWakeSlots; ++o) {
        if (source[o] < 0) {
          Wake::SetUnused(o, &p);
          continue;
        }
        Vec3 rel, vel;
        double thrust = kNaN;
        Predict(source[o], k, &rel, &vel, &thrust);
        p.segment<3>(Wake::ParamSource(o)) = rel;
        p[Wake::ParamThrust(o)] = thrust;
      }
      Vec3 lo = Vec3::Constant(-kInf), hi = Vec3::Constant(kInf);
      // With no active neighbour: zero, finite and unweighted (keeps the linearisation finite).
      // Every active neighbour bounds s, also one whose tie weight is zero.
      Vec3 rel_mean = Vec3::Zero(), vel_mean = Vec3::Zero();
      for (int j = 0; j < nn_; ++j) {
        if (!active_[j]) continue;
        Vec3 rel, vel;
        Predict(j, k, &rel, &vel);
        rel_mean += tie_[j] * rel;
        vel_mean += tie_[j] * vel;
        ocp::quadrotor::IntersectRelativeBound(rel, b + disagreement_[j], &lo, &hi);
      }
      if (active_count_ > 0) {
        rel_mean /= active_count_;
        vel_mean /= active_count_;
      }
      p.segment<3>(Reduced::ParamRelPos(0)) = rel_mean;
      p.segment<3>(Reduced::ParamVel(0)) = vel_mean;
      p.segment<3>(Problem::kParamAcceleration) = in.disturbance;
      for (int o = 0; o < kObstacleSlots; ++o) {
        if (o >= in.obstacles) {
          Base::SetUnused(o, &p);
          continue;
        }
        p.segment<3>(Base::ParamObstacle(o)) = ObstacleAt(in, o, k * ts);
        p.segment<3>(Base::ParamNormal(o)) = in.obstacle_normal[o];
      }
      if (height_known) {
        lo.z() = std::max(lo.z(), c_.safety.min_altitude - in.height);
        hi.z() = std::min(hi.z(), c_.safety.max_altitude - in.height);
      }
      solver_.SetParameters(k, p);
      if (k >= 1) {
        lb.head<3>() = lo;
        ub.head<3>() = hi;
        solver_.SetStateBounds(k, lb, ub);
      }
    }
    X x0;
    x0 << Vec3::Zero(), in.own, in.last_command;
    return x0;
  }

  // sum over stages of 0.5 sum_j w_j |a_j - a_w|_W^2 (position and velocity rows; see the
  // class comment): the per-neighbour cost minus the aggregated one, at the current iterate's
  // yaw.
  double SpreadCost() const {
    if (active_count_ < 2) return 0.0;
    const Vec3 wp = c_.weights.position, wv = c_.weights.velocity;
    double sum = 0.0;
    for (int k = 0; k <= solver_.horizon(); ++k) {
      const double psi = solver_.states()[k][model::QuadrotorModel::kPsi];
      std::array<Vec3, kMaxNeighbours> a{}, v{};
      Vec3 a_mean = Vec3::Zero(), v_mean = Vec3::Zero();
      for (int j = 0; j < nn_; ++j) {
        if (!active_[j]) continue;
        Vec3 r, rel;
        Predict(j, k, &rel, &v[j]);
        ocp::RelativeRows::Write(c_.frame, rel, psi, 1.0, 0, 0, 0, &r,
                                 static_cast<Mat<3, 9>*>(nullptr));
        a[j] = r - desired_[j];
        a_mean += tie_[j] * a[j];
        v_mean += tie_[j] * v[j];
      }
      a_mean /= active_count_;
      v_mean /= active_count_;
      double stage = 0.0;
      for (int j = 0; j < nn_; ++j) {
        if (!active_[j]) continue;
        stage +=
            tie_[j] * ((a[j] - a_mean).cwiseAbs2().dot(wp) + (v[j] - v_mean).cwiseAbs2().dot(wv));
      }
      sum += 0.5 * (k < solver_.horizon() ? 1.0 : c_.weights.terminal_factor) * stage;
    }
    return sum;
  }

  ControllerConfig c_;
  double yaw_ref_ = 0.0;
  Solver solver_;
  Solver::Y w_, w_active_;
  Solver::YN wn_, wn_active_;
  int nn_ = 0, active_count_ = 0;
  std::array<bool, kMaxNeighbours> active_{};
  std::array<Vec3, kMaxNeighbours> desired_{}, rel_{}, vel_{}, acc_{};
  std::array<int, kMaxNeighbours> depth_{};        // the neighbours' graph depths (-1: unknown)
  std::array<double, kMaxNeighbours> rule_tie_{};  // TieWeights of the active set
  std::array<double, kMaxNeighbours> tie_{};       // rule_tie_ after ShareTies (sum: active_count_)
  bool discounted_ = false;                        // ShareTies discounted a weight at the last step
  // per-axis disagreement of each tie with the anchor ties (ShareTies; zero when off) [m]
  std::array<Vec3, kMaxNeighbours> disagreement_{};
  std::array<double, kMaxNeighbours> thrust_{};  // NeighbourState::thrust of the last Stage [N]
  double floor_ = -kInf;  // relative z of a neighbour resting on the ground [m] (Predict)
  const NeighbourPlans* plans_ = nullptr;  // cooperative: the plans of the last Stage (Predict)
  double t_ = 0.0;                         // time of the last Stage [s]
  std::vector<Solver::Y> yref_;
  Solver::YN yref_n_;
  std::vector<Solver::P> params_;
  X x0_ = X::Zero();
  bool first_ = true;
};

}  // namespace

std::unique_ptr<NmpcCore> MakeLeaderCore(const ControllerConfig& c) {
  return std::make_unique<LeaderCore>(c);
}

std::unique_ptr<NmpcCore> MakeFollowerCore(const ControllerConfig& c) {
  return std::make_unique<FollowerCore>(c);
}

}  // namespace fnmpc::formation

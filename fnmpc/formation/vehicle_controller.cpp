// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/vehicle_controller.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/formation/neighbour_acceleration.hpp"
#include "fnmpc/formation/neighbour_thrust.hpp"
#include "fnmpc/formation/throttle_map.hpp"
#include "fnmpc/ocp/problem_extensions.hpp"
#include "fnmpc/ocp/wake_extension.hpp"
#include "fnmpc/rti/quadrotor_ocp.hpp"

namespace fnmpc::formation {

std::string_view ToString(FlightPhase p) {
  switch (p) {
    case FlightPhase::kIdle:
      return "idle";
    case FlightPhase::kTakeoff:
      return "takeoff";
    case FlightPhase::kNmpc:
      return "nmpc";
    case FlightPhase::kLanding:
      return "landing";
    case FlightPhase::kLanded:
      return "landed";
    case FlightPhase::kFailsafe:
      return "failsafe";
  }
  return "?";
}

void ControllerConfig::Validate() const {
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("[ControllerConfig] " + what);
  };
  params.Validate();
  rti.Validate();
  if (vehicle < 0) fail("vehicle index must be >= 0, got " + std::to_string(vehicle));
  if (leader_vehicle < -1)
    fail("leader_vehicle must be >= -1, got " + std::to_string(leader_vehicle));
  if (!(thrust_min >= 0.0 && thrust_max > thrust_min)) fail("thrust bounds need 0 <= min < max");
  if (!(max_attitude_ref > 0.0 && max_attitude_ref < 1.2))
    fail("max_attitude_ref must be in (0, 1.2) rad");
  if (!(max_speed > 0.0)) fail("max_speed must be > 0");
  if (max_tracked < 1 || max_tracked > 64)
    fail("max_tracked must be in [1, 64], got " + std::to_string(max_tracked));
  const int level = static_cast<int>(compensation);
  if (level < 0 || level >= kCompensationChoice.count) {
    fail("compensation must be one of " + kCompensationChoice.Accepted());
  }
  if (level >= kCompensationChoice.available) {
    fail(std::string("compensation '") + ToString(compensation) +
         "' is not implemented yet (accepted: " + kCompensationChoice.Accepted() + ")");
  }
  if (!(plan_timeout > 0.0)) fail("plan_timeout must be > 0 s");
  if (!(attitude_offset_filter > 0.0) || !std::isfinite(attitude_offset_filter))
    fail("attitude_offset.filter_time must be finite and > 0 s");
  if (!(attitude_offset_max >= 0.0 && attitude_offset_max < max_attitude_ref))
    fail("attitude_offset.max must be in [0, bounds.attitude_ref)");
  const int rule = static_cast<int>(tie_weights);
  if (rule < 0 || rule >= kTieWeightingChoice.count)
    fail("tie_weights must be one of " + kTieWeightingChoice.Accepted());
  safety.Validate();
  if (!leader) {
    if (neighbours.empty() || neighbours.size() > static_cast<std::size_t>(kMaxNeighbours)) {
      fail("a follower needs 1 to " + std::to_string(kMaxNeighbours) + " neighbours, got " +
           std::to_string(neighbours.size()));
    }
    for (std::size_t i = 0; i < neighbours.size(); ++i) {
      const NeighbourTarget& n = neighbours[i];
      if (n.vehicle < 0 || n.vehicle == vehicle)
        fail("bad neighbour index " + std::to_string(n.vehicle));
      for (std::size_t j = 0; j < i; ++j) {
        if (neighbours[j].vehicle == n.vehicle)
          fail("neighbour " + std::to_string(n.vehicle) + " is listed twice");
      }
      if (!n.desired.allFinite()) fail("desired relative position must be finite");
    }
    if (!((relative_position_bound.array() > 0.0).all()))
      fail("relative_position_bound must be > 0");
  } else if (trajectory.empty()) {
    fail("the leader needs a trajectory");
  }
  if (!(takeoff_height > ground_height)) fail("takeoff_height must be above ground_height");
  if (!(climb_speed > 0.0) || !(descent_speed > 0.0)) fail("climb and descent speeds must be > 0");
  if (!(blend_time >= 0.0) || !(hover_before_switch >= 0.0))
    fail("blend_time, hover_before_switch >= 0");
  if (!(landing_time > takeoff_time)) fail("landing_time must be after takeoff_time");
  if (!(touchdown_margin > 0.0)) fail("touchdown_margin must be > 0");
  if (!(voltage_filter_time >= 0.0)) fail("voltage_filter_time must be >= 0");
  if (!(neighbour_acceleration_decay >= 0.0) || !std::isfinite(neighbour_acceleration_decay))
    fail("neighbour_acceleration.decay must be finite and >= 0");
  if (!(neighbour_acceleration_filter >= 0.0) || !std::isfinite(neighbour_acceleration_filter))
    fail("neighbour_acceleration.filter_time must be finite and >= 0");
  pid.Validate();
}

// ---------------------------------------------------------------------------------------
// NMPC cores. The solvers (leader, reduced follower) are instantiated implicitly in this
// translation unit.

/// What a follower estimates of one neighbour (NeighbourStateIndex layout, split).
struct NeighbourState {
  Vec3 rel_pos = Vec3::Zero();  // p_j - p_self [m]
  Vec3 vel = Vec3::Zero();      // [m/s]
  double yaw = 0.0;             // [rad]
  double yaw_rate = 0.0;        // [rad/s]
  Vec3 acc = Vec3::Zero();      // estimated acceleration [m/s^2] (AccelerationEstimate)
  double thrust = kNaN;         // its thrust estimated from acc (NeighbourThrust) [N]
};

/// Obstacle slots of the controllers' OCPs (the nearest sensed vehicles).
constexpr int kObstacleSlots = 4;
/// Wake slots of the follower's OCP (Compensation::kWake): its first active formation
/// neighbours in configuration order.
constexpr int kWakeSlots = 4;
using WakeSlots = std::array<int, kWakeSlots>;

/// The neighbours whose wakes a follower predicts (Compensation::kWake): the first kWakeSlots
/// active ones of the first `count` (configuration order); -1 marks an unused slot.
WakeSlots WakeSources(const std::array<bool, kMaxNeighbours>& active, int count) {
  WakeSlots source;
  source.fill(-1);
  for (int j = 0, o = 0; j < count && o < kWakeSlots; ++j) {
    if (active[j]) source[o++] = j;
  }
  return source;
}

/// Thrust [N] a follower assumes for a neighbour whose wake it predicts, from its estimated
/// acceleration (the filter's mixed mean: zero in the hover mode) and the own vehicle file's
/// mass, bounded to what any vehicle of the formation can be commanded (neighbour_thrust.hpp);
/// cooperative mode uses the shared plan's while it is fresh.
ThrustEstimate NeighbourThrust(const ControllerConfig& c, const Vec3& acc) {
  return ThrustFromAcceleration(c.params.mass, acc, std::max(c.thrust_max, c.pid.max_thrust));
}

/// One NMPC step's inputs: own estimate and neighbour estimates.
struct NmpcInput {
  double t = 0.0;
  Vec3 position = Vec3::Zero();  // leader only, {n}
  Vec<6> own = Vec<6>::Zero();   // v (3), roll, pitch, yaw
  double height = kNaN;          // follower: current height of the CoM [m] (NaN: unknown)
  std::array<NeighbourState, kMaxNeighbours> neighbours{};
  std::array<bool, kMaxNeighbours> active{};  // follower: neighbour j in the cost
  Vec3 last_command = Vec3::Zero();           // (thrust, roll, pitch) last applied
  // External acceleration held over the horizon ({n} = {m} axes) [m/s^2]: the own
  // estimator's d from Compensation::kObserver on, else zero. With Compensation::kWake the
  // estimator was told the wake model's part (VehicleEkf::SetCommand), so d is the rest.
  Vec3 disturbance = Vec3::Zero();
  // Compensation::kWake, follower: the wake model's acceleration at the current relative
  // positions (PredictedWake), else zero [m/s^2].
  Vec3 wake = Vec3::Zero();
  // Collision avoidance: the nearest sensed vehicles, relative position (p_o - p_self) and
  // velocity; slots beyond `obstacles` are unused.
  std::array<Vec3, kObstacleSlots> obstacle_rel{}, obstacle_vel{};
  std::array<Vec3, kObstacleSlots> obstacle_normal{};  // unit, from self towards the obstacle
  // kappa^2 n'P n of the estimate's position, position-velocity and velocity blocks along
  // the normal (ObstacleAt); zero for an estimate taken as exact.
  std::array<Vec3, kObstacleSlots> obstacle_spread{};
  int obstacles = 0;
  // Fault injection: skip the solve and apply the time-shifted plan, as on a solver error.
  bool forced_failure = false;
  // Compensation::kCooperative, follower: the neighbours' latest plans (else null).
  const NeighbourPlans* plans = nullptr;
};

/// Obstacle o's position t [s] ahead for the collision rows: its constant-velocity
/// prediction moved towards the observer along the separating normal n by the chance
/// constraint's margin kappa sigma(t), sigma(t)^2 = n'(P_pp + 2 t P_pv + t^2 P_vv) n the
/// prediction's variance from the estimate's covariance. n.(c - kappa sigma n - p) >= r_min is
/// n.(c - p) >= r_min + kappa sigma: under a Gaussian estimate the true obstacle keeps r_min
/// along n with probability Phi(kappa) (SafetyConfig::collision_confidence; docs/safety.md).
Vec3 ObstacleAt(const NmpcInput& in, int o, double t) {
  const Vec3& s = in.obstacle_spread[o];
  const double margin = std::sqrt(std::max(0.0, s[0] + 2.0 * t * s[1] + t * t * s[2]));
  return in.obstacle_rel[o] + t * in.obstacle_vel[o] - margin * in.obstacle_normal[o];
}

struct NmpcStep {
  Vec3 u = Vec3::Constant(kNaN);
  rti::RtiStats stats;
  Vec3 reference = Vec3::Constant(kNaN);
};

/// A solver with its problem data. Built with the controller (no allocation at the
/// take-off -> NMPC switch); Engage() sets what is known only then.
class NmpcCore {
 public:
  virtual ~NmpcCore() = default;
  /// Leader: the hover point at the switch; both: the yaw reference.
  virtual void Engage(const Vec3& anchor, double yaw_ref) = 0;
  /// Initial guess from the estimate: the next Step iterates to convergence.
  virtual void Start(const NmpcInput& in, const Vec3& u_guess) = 0;
  virtual NmpcStep Step(const NmpcInput& in) = 0;
  /// Attitude-reference bounds for the correction o the controller subtracts from the
  /// NMPC's roll and pitch references (InputBounds); zero: the configured bounds.
  virtual void ShiftAttitudeBounds(const Vec<2>& o) = 0;
  /// KKT value and cost of the iterate after the last Step (N more integrations).
  virtual void Diagnose(double* kkt, double* cost) = 0;
  /// Predicted positions of the current iterate; `origin` is added to a follower's
  /// displacement (the leader's states are absolute).
  virtual void Predicted(const Vec3& origin, std::vector<Vec3>* out) const = 0;
  /// The current iterate as a plan (displacements, velocities, thrusts; PlanMessage).
  virtual void Plan(PlanMessage* out) const = 0;
};

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
  rti::quadrotor::SetInputLimits(s, c.thrust_min, c.thrust_max, c.max_attitude_ref, o);
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
                c.rti, rti::quadrotor::LeaderLayout(/*altitude=*/true, /*soft=*/true)) {
    const NmpcWeights& wt = c.weights;
    w_.setZero();
    w_.head<11>() = rti::quadrotor::LeaderWeights(wt);
    w_.segment<kObstacleSlots>(11).setConstant(wt.collision);
    w_.tail<3>() << wt.thrust_rate, wt.attitude_ref_rate, wt.attitude_ref_rate;
    wn_.head<8>() = rti::quadrotor::LeaderTerminalWeights(wt);
    wn_.tail<kObstacleSlots>().setConstant(wt.collision);
    solver_.SetWeights(w_, wn_);
    InputBounds(c, &solver_);
    Solver::X lb = Solver::X::Constant(-kInf), ub = Solver::X::Constant(kInf);
    lb[2] = c.safety.min_altitude;  // z of the CoM, the ground plane at z = 0
    ub[2] = c.safety.max_altitude;
    rti::quadrotor::SetSpeedBounds(3, c.max_speed, &lb, &ub);
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
                c.rti, rti::quadrotor::ReducedFollowerLayout(/*soft_velocity=*/true)) {
    const NmpcWeights& wt = c.weights;
    w_.setZero();
    w_.head<kNyR>() = rti::quadrotor::FollowerWeights<1>(wt);
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
    rti::quadrotor::SetSpeedBounds(3, c_.max_speed, &lb, &ub);
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
        rti::quadrotor::IntersectRelativeBound(rel, b + disagreement_[j], &lo, &hi);
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

estimation::VehicleEkfConfig OwnEkfConfig(const ControllerConfig& c) {
  estimation::VehicleEkfConfig e;
  e.sensors = c.sensors;
  e.vehicle = c.vehicle;
  e.ground_height = c.leader ? c.ground_height : 0.0;
  e.command_rate_hz = 1.0 / c.rti.sample_time;  // SetCommand once per control step
  return e;
}

/// Failsafe descent without height or vertical speed: a thrust just below hover (about
/// 0.3 m/s^2 down) so that the vehicle sinks slowly instead of holding an unknown height.
constexpr double kFailsafeBlindThrustFactor = 0.97;
/// Motion-capture height: older than this is not used, a longer gap restarts its rate [s].
constexpr double kMaxMocapGap = 0.5;
/// First-order filter of the motion-capture height's rate [s] (1 mm noise at 60 Hz: about
/// 0.03 m/s left).
constexpr double kMocapRateFilterTime = 0.1;
/// Motion-capture outliers: a sample farther than this from the raw track's prediction
/// (last sample plus rate times the interval) is skipped [m], unless it is the
/// kMocapGateRun-th in a row, which restarts the track. The prediction's error is a few mm
/// (1 mm noise, the 0.1 s rate filter's lag at 5 m/s^2 is 8 mm per 60 Hz interval).
constexpr double kMocapGate = 0.1;
constexpr int kMocapGateRun = 5;
/// Consistency check: EKF velocity against the motion-capture rate [m/s], for [s].
constexpr double kVelocityMismatch = 1.0;
constexpr double kVelocityMismatchTime = 0.3;
/// A vehicle in view takes the tracking slot of the farthest tracked one only when it is
/// nearer by this much [m] (measured ranges; the range noise is centimetres).
constexpr double kTrackSwapMargin = 0.5;
/// Lateral shift of a sensed vehicle to the observer's left, as a fraction of r_min
/// (NearestObstacles: the passing rule).
constexpr double kPassingShift = 0.3;
/// A neighbour whose estimated CoM is within this of the resting height is on the ground [m].
constexpr double kGroundedMargin = 0.15;
/// Touchdown: the ground-contact condition must hold this long before the motors stop [s]
/// (PX4's multicopter land detector, LAND_DETECTOR_TRIGGER_TIME_US = 300 ms). Without it a
/// descent that starts within touchdown_margin of the ground stopped the motors at once, in
/// the air (fault campaign run 55: a 3 cm drop, 0.67 m/s at impact).
constexpr double kTouchdownConfirmTime = 0.3;
/// Landing: a site moved clear of a vehicle below is put this much beyond r_min from it [m],
/// so that estimate noise (centimetres) does not move it again at every step.
constexpr double kLandingSiteClearance = 0.1;
// A descent that has waited this long [s] above a vehicle moves its site one clearance further.
constexpr double kLandingSiteWait = 2.0;

bool Rejected(estimation::EkfStatus s) {
  using estimation::EkfStatus;
  return s == EkfStatus::kRejectedNonFinite || s == EkfStatus::kRejectedGated ||
         s == EkfStatus::kRejectedTooOld || s == EkfStatus::kRejectedInvalid ||
         s == EkfStatus::kNumericalError || s == EkfStatus::kRejectedTimeJump;
}

}  // namespace

// ---------------------------------------------------------------------------------------

VehicleController::VehicleController(const ControllerConfig& config)
    : config_((config.Validate(), config)),
      ekf_(OwnEkfConfig(config), config.params),
      wake_(config.params),
      pid_(config.pid, config.params.mass),
      ladder_(config.safety.recovery),
      collision_sigmas_(CollisionSigmas(config.safety)),
      departure_(config.safety.neighbour_departure_height, config.safety.neighbour_departure_time,
                 config.safety.neighbour_reacquire_time) {
  for (const NeighbourTarget& n : config_.neighbours) {
    estimation::NeighbourEkfConfig nc;
    nc.sensors = config_.sensors;
    nc.observer = config_.vehicle;
    nc.target = n.vehicle;
    nc.own_velocity_rate_hz = 1.0 / config_.rti.sample_time;  // PredictTo once per step
    neighbour_ekfs_.emplace_back(nc);
  }
  // Tracking slots for the other vehicles in view: what max_tracked leaves after the
  // formation neighbours, all built now (no allocation when they change hands).
  const int others =
      config_.track_others
          ? std::max(0, config_.max_tracked - static_cast<int>(config_.neighbours.size()))
          : 0;
  tracks_.reserve(static_cast<std::size_t>(others));
  for (int k = 0; k < others; ++k) {
    estimation::NeighbourEkfConfig nc;
    nc.sensors = config_.sensors;
    nc.observer = config_.vehicle;
    nc.own_velocity_rate_hz = 1.0 / config_.rti.sample_time;
    tracks_.push_back(Track{-1, kNaN, kInf, estimation::NeighbourEkf(nc), Presence{}});
  }
  const std::size_t nn = config_.neighbours.size();
  estimates_.neighbours.assign(nn, estimation::NeighbourStateVec::Constant(kNaN));
  estimates_.others.assign(tracks_.size(), estimation::NeighbourStateVec::Constant(kNaN));
  estimates_.neighbour_covariances.assign(nn, estimation::NeighbourStateCov::Zero());
  estimates_.other_covariances.assign(tracks_.size(), estimation::NeighbourStateCov::Zero());
  presence_.assign(nn, Presence{});
  // A gap of more than two missed steps restarts the derivative.
  neighbour_acceleration_.assign(nn, AccelerationEstimate(config_.neighbour_acceleration_filter,
                                                          2.5 * config_.rti.sample_time));
  attitude_offset_ = AttitudeOffset(
      config_.params.attitude_time_constant.head<2>(), config_.params.attitude_gain.head<2>(),
      config_.attitude_offset_filter, config_.attitude_offset_max, 2.5 * config_.rti.sample_time);
  std::vector<int> neighbour_vehicles;
  for (const NeighbourTarget& n : config_.neighbours) neighbour_vehicles.push_back(n.vehicle);
  plans_ = NeighbourPlans(neighbour_vehicles);
  // The solver is built here, not at the take-off -> NMPC switch: no allocation in flight.
  if (config_.leader) {
    nmpc_ = std::make_unique<LeaderCore>(config_);
  } else {
    nmpc_ = std::make_unique<FollowerCore>(config_);
  }
}

VehicleController::~VehicleController() = default;
VehicleController::VehicleController(VehicleController&&) noexcept = default;
VehicleController& VehicleController::operator=(VehicleController&&) noexcept = default;

void VehicleController::Process(const Measurement& m) {
  if (m.vehicle != config_.vehicle) return;
  switch (m.kind) {
    case SensorKind::kMocapPose:
      // The leader fuses mocap; a follower has no absolute position: only the height is
      // kept, for the take-off and landing PID.
      if (config_.leader) ekf_.Process(m);
      TrackMocapPose(m);
      break;
    case SensorKind::kCompass:
      if (!config_.leader && !ekf_.initialized() && std::isfinite(m.yaw)) {
        ekf_.Initialize(m.stamp, Vec3::Zero(), Vec3(0.0, 0.0, m.yaw));  // origin of {m}
      }
      ekf_.Process(m);
      break;
    case SensorKind::kImu:
    case SensorKind::kOpticalFlow:
      ekf_.Process(m);
      break;
    case SensorKind::kBattery:
      if (std::isfinite(m.voltage) && m.voltage > 0.0) {
        if (!std::isfinite(voltage_)) {
          voltage_ = m.voltage;
        } else {
          const double dt = std::max(0.0, m.stamp - voltage_stamp_);
          const double a = config_.voltage_filter_time > 0.0
                               ? 1.0 - std::exp(-dt / config_.voltage_filter_time)
                               : 1.0;
          voltage_ += a * (m.voltage - voltage_);
        }
        voltage_stamp_ = m.stamp;
      }
      break;
    case SensorKind::kRelative: {
      if (!ekf_.initialized()) break;
      // The target's filter: a formation neighbour's or another sensed vehicle's.
      estimation::NeighbourEkf* filter = nullptr;
      Presence* presence = nullptr;
      for (std::size_t j = 0; j < config_.neighbours.size() && !filter; ++j) {
        if (config_.neighbours[j].vehicle != m.relative.target) continue;
        filter = &neighbour_ekfs_[j];
        presence = &presence_[j];
      }
      Track* track = nullptr;
      if (filter == nullptr && m.relative.target != config_.vehicle) {
        track = TrackOf(m.relative.target, m.stamp, m.relative.range);
        if (track != nullptr) {
          filter = &track->ekf;
          presence = &track->presence;
          if (std::isfinite(m.relative.range)) track->range = m.relative.range;
        }
      }
      if (filter == nullptr) break;
      const OwnAtStamp& own = OwnAt(m.stamp);
      if (filter->Process(m, own.euler, own.velocity, &own.euler_cov) ==
              estimation::EkfStatus::kAccepted &&
          std::isfinite(m.stamp)) {
        presence->Accept(m.stamp, config_.safety.neighbour_reacquire_time);
      }
      break;
    }
  }
}

const VehicleController::OwnAtStamp& VehicleController::OwnAt(double stamp) {
  OwnAtStamp& own = own_at_relative_;
  // NaN never equals itself: a non-finite stamp is predicted anew (and rejected downstream).
  if (own.stamp == stamp && own.revision == ekf_.revision()) return own;
  const estimation::VehicleEstimate e = ekf_.Estimate(stamp);
  own.stamp = stamp;
  own.revision = ekf_.revision();
  own.euler = e.euler;
  own.velocity = e.velocity;
  own.euler_cov = e.covariance.block<3, 3>(estimation::VehicleStateIndex::kEuler,
                                           estimation::VehicleStateIndex::kEuler);
  return own;
}

// The slot of another vehicle in view: its own, else a free one (never given, or its vehicle
// unmeasured for neighbour_timeout: out of view), else the slot of the farthest tracked
// vehicle when this one is nearer by kTrackSwapMargin (nearest first, without two vehicles
// at about the same range taking the slot from each other at every measurement). nullptr:
// not tracked. The slot's filter restarts for its new vehicle; no allocation.
VehicleController::Track* VehicleController::TrackOf(int vehicle, double stamp, double range) {
  for (Track& k : tracks_) {
    if (k.vehicle == vehicle) return &k;
  }
  if (!std::isfinite(stamp) || !std::isfinite(range)) return nullptr;
  Track* slot = nullptr;
  for (Track& k : tracks_) {
    if (k.vehicle < 0 || TrackLost(k, stamp)) {
      slot = &k;
      break;
    }
  }
  if (slot == nullptr) {
    for (Track& k : tracks_) {
      if (slot == nullptr || k.range > slot->range) slot = &k;
    }
    if (slot == nullptr || !(range + kTrackSwapMargin < slot->range)) return nullptr;
  }
  slot->vehicle = vehicle;
  slot->assigned = stamp;
  slot->range = range;
  slot->presence = Presence{};
  slot->ekf.Retarget(vehicle);
  return slot;
}

// A tracked vehicle with no accepted measurement (or, never accepted, since its slot was
// given) for neighbour_timeout at t: out of view; its slot is free.
bool VehicleController::TrackLost(const Track& k, double t) const {
  const double last = std::isfinite(k.presence.seen) ? k.presence.seen : k.assigned;
  return !(t - last <= config_.safety.neighbour_timeout);
}

void VehicleController::Presence::Accept(double stamp, double max_gap) {
  if (!std::isfinite(seen) || stamp - seen > max_gap) seen_since = stamp;
  seen = std::isfinite(seen) ? std::max(seen, stamp) : stamp;
}

std::int64_t VehicleController::estimator_rejections() const {
  std::int64_t n = 0;
  for (int s = 0; s < estimation::kNumEkfStatus; ++s) {
    if (!Rejected(static_cast<estimation::EkfStatus>(s))) continue;
    n += ekf_.counters().Total(static_cast<estimation::EkfStatus>(s));
    for (const auto& f : neighbour_ekfs_)
      n += f.counters().Total(static_cast<estimation::EkfStatus>(s));
    for (const Track& k : tracks_)
      n += k.ekf.counters().Total(static_cast<estimation::EkfStatus>(s));
  }
  return n;
}

// The take-off and landing PID's horizontal error: hold point minus the own position estimate
// (a follower's is dead-reckoned from its velocity, drift-free enough over one phase).
Vec<2> VehicleController::HoldError() const { return hold_xy_ - estimates_.own.position.head<2>(); }

double VehicleController::Height(double t) const {
  const auto& own = estimates_.own;
  if (config_.leader) return own.valid ? own.position.z() : kNaN;
  // A follower: the raw motion-capture height while it is fresh. A stale one would freeze
  // the height the take-off, landing and failsafe loops close on, and the failsafe's
  // descent would speed up towards its falling reference (fault campaign run 8: mocap lost
  // in the descent, touchdown at -0.8 m/s); after kMaxMocapGap the estimate's.
  if (RawMocapFresh(t)) return raw_z_;
  return own.valid ? config_.ground_height + own.position.z() : kNaN;
}

void VehicleController::Blend(double t, double* thrust, double* roll, double* pitch) const {
  if (!blend_from_.allFinite() || !(config_.blend_time > 0.0)) return;
  const double a = std::clamp((t - blend_start_) / config_.blend_time, 0.0, 1.0);
  *thrust = (1.0 - a) * blend_from_[0] + a * *thrust;
  *roll = (1.0 - a) * blend_from_[1] + a * *roll;
  *pitch = (1.0 - a) * blend_from_[2] + a * *pitch;
}

// Hysteresis on the neighbours' accepted relative measurements: lost after
// neighbour_timeout without one, back after a run of neighbour_reacquire_time. A neighbour
// seen on the ground (its estimated CoM height, own height plus the relative offset, within
// kGroundedMargin of the resting height) for neighbour_timeout is lost too: a landed or
// fallen vehicle cannot be kept in formation; it returns once airborne again for
// neighbour_reacquire_time.
void VehicleController::UpdateNeighbourPresence(double t) {
  const double z = Height(t);
  const SafetyConfig& sc = config_.safety;
  if (std::isfinite(nmpc_start_)) {  // neighbours leaving the formation (formation_ties.hpp)
    std::array<TieView, kMaxNeighbours> views;
    for (std::size_t j = 0; j < presence_.size(); ++j) {
      const Presence& p = presence_[j];
      const auto& x = estimates_.neighbours[j];
      views[j] = {x[2], config_.neighbours[j].desired.z(),
                  config_.neighbours[j].vehicle == config_.leader_vehicle,
                  std::isfinite(p.seen) && t - p.seen <= sc.neighbour_timeout &&
                      x.head<3>().allFinite() && !(p.landed && !p.active)};
    }
    departure_.Update(t, views.data(), static_cast<int>(presence_.size()));
  }
  UpdateLeaderSeenDown(t, z);
  for (std::size_t j = 0; j < presence_.size(); ++j) {
    Presence& p = presence_[j];
    const bool fresh = std::isfinite(p.seen) && t - p.seen <= sc.neighbour_timeout;
    const bool departed = departure_.departed(static_cast<int>(j));
    const double zj = z + estimates_.neighbours[j][2];
    const bool grounded = std::isfinite(zj) && zj < config_.ground_height + kGroundedMargin;
    p.grounded.Update(grounded, t);
    const bool landed = p.grounded.For(t, sc.neighbour_timeout);
    if (p.active && (!fresh || landed || departed) && std::isfinite(nmpc_start_)) {
      if (fresh && !landed) ++neighbour_departures_;
      p.active = false;
      p.landed = landed;
      p.airborne.Reset();
    } else if (!p.active && fresh && !grounded && !departed) {
      p.airborne.Start(t);
      const bool run = p.seen - p.seen_since >= sc.neighbour_reacquire_time;
      const bool airborne = !p.landed || p.airborne.For(t, sc.neighbour_reacquire_time);
      if (run && airborne) p.active = true;
    } else if (grounded) {
      p.airborne.Reset();
    }
  }
}

// The leader seen on the ground for neighbour_timeout in a tracking slot (a follower that
// does not have it as a formation neighbour but senses it; the same test as the neighbours').
void VehicleController::UpdateLeaderSeenDown(double t, double z) {
  leader_seen_down_ = false;
  if (config_.leader || config_.leader_vehicle < 0) return;
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    Presence& p = tracks_[k].presence;
    if (tracks_[k].vehicle != config_.leader_vehicle) continue;
    const double zl = z + estimates_.others[k][2];
    const bool fresh = std::isfinite(p.seen) && t - p.seen <= config_.safety.neighbour_timeout;
    p.grounded.Update(fresh && std::isfinite(zl) && zl < config_.ground_height + kGroundedMargin,
                      t);
    leader_seen_down_ = leader_seen_down_ || p.grounded.For(t, config_.safety.neighbour_timeout);
  }
}

// Every formation tie to the leader lost (TieLoss): the leader down, or every neighbour
// landed or gone from the formation.
RecoveryReason VehicleController::TieLossNow() const {
  std::array<TieState, kMaxNeighbours> ties;
  for (std::size_t j = 0; j < presence_.size(); ++j) {
    const Presence& p = presence_[j];
    ties[j] = {config_.neighbours[j].vehicle == config_.leader_vehicle, p.active,
               p.landed && !p.active, departure_.departed(static_cast<int>(j))};
  }
  return TieLoss(ties.data(), static_cast<int>(presence_.size()), leader_seen_down_);
}

// Raw motion-capture pose and its filtered rate, kept apart from the EKF: the failsafe and
// the consistency check must not depend on the estimate they check.
void VehicleController::TrackMocapPose(const Measurement& m) {
  if (!m.position.allFinite() || !std::isfinite(m.stamp)) return;
  const double dt = std::isfinite(raw_z_stamp_) ? m.stamp - raw_z_stamp_ : kInf;
  if (!(dt > 0.0)) return;  // out of order or repeated: keep the newer sample
  if (dt <= kMaxMocapGap && raw_v_.allFinite() &&
      (m.position - (raw_p_ + dt * raw_v_)).cwiseAbs().maxCoeff() > kMocapGate &&
      raw_rejected_in_row_ < kMocapGateRun) {
    ++raw_rejected_in_row_;  // an outlier: the raw height and rate skip it
    return;
  }
  const bool restart = raw_rejected_in_row_ >= kMocapGateRun;  // the track itself jumped
  raw_rejected_in_row_ = 0;
  if (dt <= kMaxMocapGap && !restart) {
    const double a = 1.0 - std::exp(-dt / kMocapRateFilterTime);
    const Vec3 rate = (m.position - raw_p_) / dt;
    raw_v_ = raw_v_.allFinite() ? Vec3(raw_v_ + a * (rate - raw_v_)) : rate;
  } else {
    raw_v_.setConstant(kNaN);  // a gap: restart the rate
  }
  raw_p_ = m.position;
  raw_z_ = m.position.z();
  raw_yaw_ = m.euler.z();
  raw_z_stamp_ = m.stamp;
}

bool VehicleController::RawMocapFresh(double t) const {
  return std::isfinite(raw_z_stamp_) && t - raw_z_stamp_ <= kMaxMocapGap;
}

// The EKF's velocity against the motion-capture rate: a disagreement above
// kVelocityMismatch on any axis for longer than kVelocityMismatchTime marks the estimate
// unusable (an integrating velocity estimate, e.g. without optical flow, diverges long
// before its covariance says so). Needs motion capture; without it nothing is checked.
void VehicleController::CheckVelocityConsistency(double t) {
  const Vec3& v = estimates_.own.velocity;
  if (!RawMocapFresh(t) || !raw_v_.allFinite() || !v.allFinite()) {
    velocity_mismatch_.Reset();
    return;
  }
  velocity_mismatch_.Update((v - raw_v_).cwiseAbs().maxCoeff() > kVelocityMismatch, t);
}

bool VehicleController::VelocityInconsistent(double t) const {
  return velocity_mismatch_.For(t, kVelocityMismatchTime);
}

// The NMPC can run on the estimate: the own state is valid and finite and (follower) at
// least one neighbour in the cost has a finite estimate.
bool VehicleController::EstimateUsable(double t) const {
  const auto& own = estimates_.own;
  if (!own.valid || !own.velocity.allFinite() || !own.euler.allFinite()) return false;
  if (VelocityInconsistent(t)) return false;
  if (config_.leader) return own.position.allFinite();
  bool any = false;
  for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
    if (presence_[j].active && estimates_.neighbours[j].allFinite()) any = true;
  }
  return any;
}

// The kObstacleSlots nearest tracked vehicles (formation neighbours and others) with a
// finite estimate and an accepted measurement within neighbour_timeout: the last valid
// estimate is kept while it is that fresh. No allocation (fixed arrays).
template <class Input>
void VehicleController::NearestObstacles(double t, Input* in) const {
  in->obstacles = 0;
  if (!(config_.safety.collision_radius > 0.0)) return;
  const double timeout = config_.safety.neighbour_timeout;
  std::array<double, kObstacleSlots> dist{};
  const double kappa2 = collision_sigmas_ * collision_sigmas_;
  auto offer = [&](const estimation::NeighbourStateVec& x, const estimation::NeighbourStateCov& cov,
                   double seen) {
    if (!x.allFinite() || !std::isfinite(seen) || t - seen > timeout) return;
    const double d = x.head<3>().norm();
    int pos = in->obstacles;
    if (pos == kObstacleSlots) {
      if (d >= dist[kObstacleSlots - 1]) return;
      pos = kObstacleSlots - 1;
    } else {
      ++in->obstacles;
    }
    // Insertion into the slots sorted by distance.
    for (; pos > 0 && dist[pos - 1] > d; --pos) {
      dist[pos] = dist[pos - 1];
      in->obstacle_rel[pos] = in->obstacle_rel[pos - 1];
      in->obstacle_vel[pos] = in->obstacle_vel[pos - 1];
      in->obstacle_normal[pos] = in->obstacle_normal[pos - 1];
      in->obstacle_spread[pos] = in->obstacle_spread[pos - 1];
    }
    dist[pos] = d;
    in->obstacle_rel[pos] = x.head<3>();
    in->obstacle_vel[pos] = x.segment<3>(3);
    // Separating plane through the current geometry, its normal tilted to the observer's
    // left (a right-hand passing rule without communication): two vehicles heading at each
    // other both give way to their right instead of mirroring each other's manoeuvre.
    const Vec3 rel = x.head<3>();
    const double h = rel.head<2>().norm();
    const Vec3 left = h > 1e-6 ? Vec3(-rel.y() / h, rel.x() / h, 0.0) : Vec3::Zero();
    const Vec3 n = rel + kPassingShift * config_.safety.collision_radius * left;
    in->obstacle_normal[pos] = n.norm() > 1e-9 ? Vec3(n.normalized()) : Vec3(0.0, 0.0, 1.0);
    // The chance constraint's margin (ObstacleAt); a non-finite covariance gives none.
    const Vec3& u = in->obstacle_normal[pos];
    const Vec3 spread(u.dot(cov.block<3, 3>(0, 0) * u), u.dot(cov.block<3, 3>(0, 3) * u),
                      u.dot(cov.block<3, 3>(3, 3) * u));
    in->obstacle_spread[pos] = spread.allFinite() ? Vec3(kappa2 * spread) : Vec3(Vec3::Zero());
  };
  for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
    offer(estimates_.neighbours[j], estimates_.neighbour_covariances[j], presence_[j].seen);
  }
  for (std::size_t k = 0; k < tracks_.size(); ++k)
    offer(estimates_.others[k], estimates_.other_covariances[k], tracks_[k].presence.seen);
}

ControlOutput VehicleController::Control(double t) {
  estimates_.own = ekf_.initialized() ? ekf_.Estimate(t) : estimation::VehicleEstimate{};
  const estimation::VehicleEstimate& own = estimates_.own;
  // Every tracked vehicle predicted to t (NaN while its filter has nothing to go on).
  const auto predict = [&](estimation::NeighbourEkf& f, estimation::NeighbourStateVec& out,
                           estimation::NeighbourStateCov& cov) {
    if (f.initialized() && own.valid && own.velocity.allFinite()) {
      f.PredictTo(t, own.velocity);
      const estimation::NeighbourEstimate e = f.EstimateAt(t, own.velocity);
      out = e.x;
      cov = e.covariance;
    } else {
      out.setConstant(kNaN);
      cov.setZero();
    }
  };
  for (std::size_t j = 0; j < neighbour_ekfs_.size(); ++j) {
    predict(neighbour_ekfs_[j], estimates_.neighbours[j], estimates_.neighbour_covariances[j]);
  }
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    Track& track = tracks_[k];
    if (track.vehicle >= 0 && TrackLost(track, t)) track.vehicle = -1;  // out of view: free
    if (track.vehicle >= 0) {
      predict(track.ekf, estimates_.others[k], estimates_.other_covariances[k]);
    } else {
      estimates_.others[k].setConstant(kNaN);
      estimates_.other_covariances[k].setZero();
    }
  }
  UpdateNeighbourPresence(t);
  CheckVelocityConsistency(t);
  const ControlOutput out = Step(t);
  // The wake model's part of the external acceleration (Compensation::kWake) is known to the
  // estimator, whose d then carries the rest only (no double counting in the prediction).
  if (ekf_.initialized()) ekf_.SetCommand(t, out.thrust, out.roll, out.pitch, out.yaw, out.wake);
  return out;
}

void VehicleController::Diagnose(ControlOutput* out) {
  if (out == nullptr || !out->nmpc || !nmpc_started_) return;
  nmpc_->Diagnose(&out->kkt, &out->cost);
}

bool VehicleController::ReceivePlan(const PlanMessage& m) { return plans_.Receive(m); }

bool VehicleController::MakePlan(PlanMessage* out) const {
  if (!std::isfinite(plan_time_) || phase_ != FlightPhase::kNmpc || !nmpc_started_) return false;
  out->vehicle = config_.vehicle;
  out->stamp = plan_time_;
  out->sample_time = config_.rti.sample_time;
  out->disturbance = plan_disturbance_.allFinite() ? plan_disturbance_ : Vec3(Vec3::Zero());
  nmpc_->Plan(out);
  return out->Valid();
}

std::vector<Vec3> VehicleController::PredictedPositions() const {
  std::vector<Vec3> out;
  if (phase_ != FlightPhase::kNmpc || !nmpc_started_) return out;
  const Vec3 origin =
      estimates_.own.position.allFinite() ? Vec3(estimates_.own.position) : Vec3(Vec3::Zero());
  nmpc_->Predicted(origin, &out);
  return out;
}

ControlOutput VehicleController::ControlWithEstimates(
    double t, const estimation::VehicleEstimate& own,
    const std::vector<estimation::NeighbourStateVec>& neighbours,
    const std::vector<estimation::NeighbourStateCov>* covariances) {
  estimates_.own = own;
  for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
    estimates_.neighbours[j] =
        j < neighbours.size() ? neighbours[j] : estimation::NeighbourStateVec::Constant(kNaN);
    estimates_.neighbour_covariances[j] = covariances != nullptr && j < covariances->size()
                                              ? (*covariances)[j]
                                              : estimation::NeighbourStateCov::Zero();
    // Given estimates count as fresh measurements of the neighbours they describe.
    if (estimates_.neighbours[j].allFinite()) {
      presence_[j].Accept(t, config_.safety.neighbour_reacquire_time);
    }
  }
  UpdateNeighbourPresence(t);
  CheckVelocityConsistency(t);
  return Step(t);
}

// Take-off and landing PID: an estimate unusable for estimate_timeout (the ladder's timer)
// hands over to the failsafe. Returns true when it did.
bool VehicleController::PidEstimateLost(double t, double z, ControlOutput* out) {
  const auto& own = estimates_.own;
  const bool usable = own.valid && std::isfinite(z) && own.velocity.allFinite() &&
                      own.euler.allFinite() && !VelocityInconsistent(t);
  const RecoveryDecision d = ladder_.Update(t, usable, false);
  if (d.action != RecoveryAction::kFailsafe) return false;
  out->recovery = d.action;
  out->recovery_reason = d.reason;
  EnterFailsafe(t, d.reason);
  return true;
}

void VehicleController::TriggerFailsafe(double t) {
  if (phase_ == FlightPhase::kLanded || phase_ == FlightPhase::kIdle || ladder_.failsafe()) return;
  ladder_.Trigger(RecoveryReason::kCommanded);
  EnterFailsafe(t, RecoveryReason::kCommanded);
}

void VehicleController::EnterFailsafe(double t, RecoveryReason reason) {
  failsafe_reason_ = reason;
  phase_ = FlightPhase::kFailsafe;
  phase_start_ = t;
  contact_.Reset();
  const double z = FailsafeHeight(t);
  z_ref_ = std::isfinite(z) ? z : kNaN;
  pid_.Reset(std::isfinite(last_command_[0]) ? last_command_[0] : config_.params.mass * kGravity);
  blend_from_ = Vec3::Constant(kNaN);  // the failsafe acts at once
}

// The failsafe's height: the raw motion-capture height when fresh, else the controller's
// height if the estimate is still valid.
double VehicleController::FailsafeHeight(double t) const {
  if (RawMocapFresh(t)) return raw_z_;
  return estimates_.own.valid && !VelocityInconsistent(t) ? Height(t) : kNaN;
}

// Touchdown: on the ground (height within the margin) and no longer moving down, so the
// motors never stop while the vehicle still falls, for kTouchdownConfirmTime without a
// break: a vehicle hovering a few centimetres up when its reference passes the ground is
// still flying, and the PID brings it down within that time.
bool VehicleController::TouchedDown(double t, double z, double vz) {
  const double ground = config_.ground_height;
  const bool settled = std::isfinite(vz) && std::abs(vz) < 0.1;
  const bool contact = std::isfinite(z) && z < ground + config_.touchdown_margin &&
                       z_ref_ < ground && (settled || z_ref_ <= ground - 0.3);
  contact_.Update(contact, t);
  return contact_.For(t, kTouchdownConfirmTime - 1e-9);
}

// Landing clear of other vehicles: every sensed vehicle (formation neighbour or other, finite
// estimate, an accepted measurement within neighbour_timeout, as for collision avoidance)
// that is not clearly above (its CoM less than r_min higher) and within r_min of the landing
// site horizontally moves the site away from it, to r_min + kLandingSiteClearance (along the
// line from it through the site, else through the own position, else +x). The PID flies
// there; the descent waits while the vehicle itself is within r_min of one of them
// horizontally and less than 2 r_min above it (higher up it descends while it moves: the
// landing from the take-off height fits its time). A vehicle can hold off its site (the PID's
// offset under an attitude bias, until its slow integral removes it: 0.37 m from a grounded
// vehicle with the site at 0.55 m, waiting past the end of the run), so after kLandingSiteWait
// of waiting the site moves kLandingSiteClearance further from the vehicle it waits for, and
// again after each further kLandingSiteWait. Returns true while the descent waits; a move is
// logged in `out`.
bool VehicleController::ClearLandingSite(double t, ControlOutput* out) {
  const double r = config_.safety.collision_radius;
  const Vec3& p = estimates_.own.position;
  if (!(r > 0.0) || !hold_xy_.allFinite() || !p.head<2>().allFinite()) return false;
  const double timeout = config_.safety.neighbour_timeout;
  bool wait = false;
  auto shift = [&](const Vec<2>& site) {
    hold_xy_ = site;
    ++landing_site_shifts_;
    if (out->recovery == RecoveryAction::kNone) {  // a kLand of the same step is kept
      out->recovery = RecoveryAction::kShiftLandingSite;
      out->recovery_reason = RecoveryReason::kVehicleBelow;
    }
  };
  auto check = [&](const estimation::NeighbourStateVec& x, double seen) {
    if (!x.head<3>().allFinite() || !std::isfinite(seen) || t - seen > timeout) return;
    if (x[2] >= r) return;  // clearly above: not in the descent's way
    const Vec<2> o = p.head<2>() + x.head<2>();
    Vec<2> away = hold_xy_ - o;
    if (away.norm() < r) {
      if (away.norm() < 1e-3) away = -x.head<2>();
      if (away.norm() < 1e-3) away = Vec<2>(1.0, 0.0);
      shift(o + (r + kLandingSiteClearance) * away.normalized());
    }
    if (x.head<2>().norm() < r && -x[2] < 2.0 * r) {
      wait = true;
      if (!std::isfinite(site_wait_start_)) site_wait_start_ = t;
      if (t - site_wait_start_ >= kLandingSiteWait && x.head<2>().norm() > 1e-3) {
        shift(hold_xy_ - kLandingSiteClearance * x.head<2>().normalized());
        site_wait_start_ = t;
      }
    }
  };
  // Two passes: a move away from one vehicle may bring the site near another.
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j)
      check(estimates_.neighbours[j], presence_[j].seen);
    for (std::size_t k = 0; k < tracks_.size(); ++k)
      check(estimates_.others[k], tracks_[k].presence.seen);
  }
  if (!wait) site_wait_start_ = kNaN;
  return wait;
}

// PID landing from here: the height held from where it is, the position from the own
// estimate, the command blended from the last one.
void VehicleController::BeginLanding(double t, double z) {
  phase_ = FlightPhase::kLanding;
  phase_start_ = t;
  contact_.Reset();
  z_ref_ = std::isfinite(z) ? z : config_.takeoff_height;
  hold_xy_ = estimates_.own.position.head<2>();
  site_wait_start_ = kNaN;
  // From the recent mean thrust, not the last command: the PID's integral is the thrust
  // that holds the vehicle, and the landing may start close to the ground.
  const double thrust = std::isfinite(mean_thrust_) ? mean_thrust_ : last_command_[0];
  pid_.Reset(thrust);
  blend_from_ = Vec3(thrust, last_command_[1], last_command_[2]);
  blend_start_ = t;
}

ControlOutput VehicleController::Step(double t) {
  const double dt =
      std::isfinite(last_time_) ? std::max(0.0, t - last_time_) : config_.rti.sample_time;
  last_time_ = t;
  plan_time_ = kNaN;  // set again when this step runs the NMPC (MakePlan)
  ControlOutput out;
  out.time = t;
  out.voltage = voltage_;
  const estimation::VehicleEstimate& own = estimates_.own;
  if (!std::isfinite(yaw_ref_) && own.valid && std::isfinite(own.euler.z()))
    yaw_ref_ = own.euler.z();
  out.yaw = std::isfinite(yaw_ref_) ? yaw_ref_ : 0.0;
  for (const Presence& p : presence_) out.active_neighbours += p.active ? 1 : 0;

  double thrust = kNaN, roll = kNaN, pitch = kNaN;
  const double z = Height(t);
  const double ground = config_.ground_height;
  const double h = config_.takeoff_height;

  // ---- Phase logic.
  if (phase_ == FlightPhase::kIdle && t >= config_.takeoff_time && own.valid && std::isfinite(z) &&
      std::isfinite(yaw_ref_)) {
    phase_ = FlightPhase::kTakeoff;
    phase_start_ = t;
    z_ref_ = z;
    hold_xy_ = own.position.head<2>();
    height_error_lp_ = kNaN;
    pid_.Reset(config_.params.mass * kGravity);
  }
  if (phase_ == FlightPhase::kNmpc && t >= config_.landing_time) BeginLanding(t, z);
  // A follower without a formation tie to the leader lands where it is (docs/safety.md).
  if (phase_ == FlightPhase::kNmpc && !config_.leader) {
    const RecoveryReason lost = TieLossNow();
    if (lost != RecoveryReason::kNone) {
      tie_loss_ = lost;
      BeginLanding(t, z);
      out.recovery = RecoveryAction::kLand;
      out.recovery_reason = lost;
    }
  }

  switch (phase_) {
    case FlightPhase::kIdle:
    case FlightPhase::kLanded:
      thrust = roll = pitch = 0.0;
      break;
    case FlightPhase::kTakeoff: {
      if (PidEstimateLost(t, z, &out)) break;
      double vz_ref = 0.0;
      if (z_ref_ < h) {
        z_ref_ = std::min(h, z_ref_ + config_.climb_speed * dt);
        vz_ref = z_ref_ < h ? config_.climb_speed : 0.0;
      }
      const PidCommand c = pid_.Update(dt, z_ref_, vz_ref, z, own.velocity, own.euler, HoldError());
      thrust = c.thrust;
      roll = c.roll;
      pitch = c.pitch;
      // At height: the height error low-passed over a third of the hover time within
      // kAtHeightTolerance and every sample within kAtHeightBand, for hover_before_switch. The
      // filter lets a gusty push average out (another vehicle's turbulent wake); requiring
      // every sample within the tolerance held a follower under its leader in the take-off
      // for 5-43 s (docs/results.md "Faults and safety"). A steady offset still blocks.
      if (z_ref_ >= h && std::isfinite(z)) {
        const double tau = std::max(config_.hover_before_switch / 3.0, dt);
        const double e = z - h;
        height_error_lp_ = std::isfinite(height_error_lp_)
                               ? height_error_lp_ + (e - height_error_lp_) * std::min(1.0, dt / tau)
                               : e;
      }
      at_height_.Update(z_ref_ >= h && std::abs(z - h) < kAtHeightBand &&
                            std::abs(height_error_lp_) < kAtHeightTolerance,
                        t);
      const bool neighbours_ok =
          std::all_of(estimates_.neighbours.begin(), estimates_.neighbours.end(),
                      [](const estimation::NeighbourStateVec& x) { return x.allFinite(); });
      if (at_height_.For(t, config_.hover_before_switch) && neighbours_ok &&
          last_command_.allFinite()) {
        // Smooth switch: the NMPC starts from the PID's last command (guess and blend).
        phase_ = FlightPhase::kNmpc;
        phase_start_ = t;
        nmpc_start_ = t;
        blend_from_ = last_command_;
        blend_start_ = t;
        if (config_.leader) anchor_ = Vec3(own.position.x(), own.position.y(), h);
        nmpc_->Engage(anchor_, yaw_ref_);
        attitude_offset_.Reset();
        applied_offset_.setZero();
        nmpc_->ShiftAttitudeBounds(applied_offset_);
        reinit_pending_ = true;  // the first step iterates to convergence
      }
      break;
    }
    case FlightPhase::kNmpc:
      break;  // below
    case FlightPhase::kLanding: {
      if (PidEstimateLost(t, z, &out)) break;
      // Not onto another vehicle: move the site clear, descend once not right above it.
      const bool wait = ClearLandingSite(t, &out);
      const double vz_ref = wait ? 0.0 : -config_.descent_speed;
      if (!wait) z_ref_ = std::max(ground - 0.3, z_ref_ - config_.descent_speed * dt);
      const PidCommand c = pid_.Update(dt, z_ref_, vz_ref, z, own.velocity, own.euler, HoldError());
      thrust = c.thrust;
      roll = c.roll;
      pitch = c.pitch;
      Blend(t, &thrust, &roll, &pitch);
      if (TouchedDown(t, z, own.velocity.z())) {
        phase_ = FlightPhase::kLanded;
        phase_start_ = t;
        thrust = roll = pitch = 0.0;
      }
      break;
    }
    case FlightPhase::kFailsafe:
      break;  // below
  }

  if (phase_ == FlightPhase::kNmpc) {
    RecoveryDecision d;
    if (EstimateUsable(t)) {
      NmpcInput in;
      in.t = t;
      in.position = own.position;
      in.own << own.velocity, own.euler;
      in.height = z;
      // Compensation::kWake: the neighbours' thrusts from their estimated accelerations.
      const bool wake_thrust = config_.compensation >= Compensation::kWake && !config_.leader;
      for (std::size_t j = 0; j < estimates_.neighbours.size(); ++j) {
        const auto& x = estimates_.neighbours[j];
        in.active[j] = presence_[j].active && x.allFinite();
        in.neighbours[j] = {x.segment<3>(0), x.segment<3>(3), x[6], x[7], Vec3::Zero(), kNaN};
        if (config_.neighbour_acceleration_decay > 0.0 || wake_thrust) {
          const Vec3 acc = MixedAcceleration(neighbour_ekfs_[j].hover_probability(),
                                             neighbour_acceleration_[j].Update(t, x.segment<3>(3)));
          if (config_.neighbour_acceleration_decay > 0.0) in.neighbours[j].acc = acc;
          if (wake_thrust) {
            // Once per neighbour and step (the horizon holds it): the wake model's thrust.
            const ThrustEstimate T = NeighbourThrust(config_, acc);
            in.neighbours[j].thrust = T.thrust;
            if (T.bound != ThrustBound::kNone) {
              ++out.neighbour_thrust_bounded;
              out.neighbour_thrust_bound = T.bound;
            }
          }
        }
      }
      in.last_command = last_command_.allFinite() ? last_command_
                                                  : Vec3(config_.params.mass * kGravity, 0.0, 0.0);
      // The NMPC's own input frame: the last reference sent plus the correction it carried.
      in.last_command.tail<2>() += applied_offset_;
      // Offset-free attitude (Compensation::kObserver on, after the blend from the take-off
      // PID): the offset estimate from the attitude measured now and the reference sent last
      // step, and the correction this step's reference carries (AttitudeOffset).
      if (config_.compensation >= Compensation::kObserver &&
          !(t < blend_start_ + config_.blend_time)) {
        attitude_offset_.Observe(t, own.euler.head<2>());
        applied_offset_ = attitude_offset_.reference_offset();
        nmpc_->ShiftAttitudeBounds(applied_offset_);
        out.attitude_offset_bounded = attitude_offset_.bounded();
      }
      out.attitude_offset = attitude_offset_.offset();
      // A non-finite estimate of d never enters the prediction (zero: today's controller).
      if (config_.compensation >= Compensation::kObserver && own.disturbance.allFinite()) {
        in.disturbance = own.disturbance;
      }
      if (config_.compensation >= Compensation::kCooperative && !config_.leader) {
        in.plans = &plans_;
      }
      if (config_.compensation >= Compensation::kWake && !config_.leader) {
        const WakeSlots source =
            WakeSources(in.active, static_cast<int>(config_.neighbours.size()));
        for (const int j : source) {
          if (j < 0) continue;
          // The planned thrust now when the neighbour's plan is fresh (cooperative).
          PlanPrediction plan;
          const bool planned =
              in.plans != nullptr &&
              plans_.Predict(j, t, 0.0, config_.plan_timeout, in.neighbours[j].rel_pos,
                             in.neighbours[j].vel, &plan);
          const double thrust = planned ? plan.thrust : in.neighbours[j].thrust;
          in.wake.z() += wake_.Acceleration(-in.neighbours[j].rel_pos, thrust);
        }
        if (!in.wake.allFinite()) in.wake.setZero();
      }
      out.wake = in.wake;
      out.disturbance = in.disturbance + in.wake;
      plan_disturbance_ = out.disturbance;
      NearestObstacles(t, &in);
      // Fault injection (SafetyConfig::injected_failure_rate, 0 = off).
      in.forced_failure =
          InjectedSolverFailure(config_.safety, config_.vehicle, t, config_.rti.sample_time);
      if (reinit_pending_) {
        const Vec3 guess = in.last_command;
        nmpc_->Start(in, guess);
        reinit_pending_ = false;
        nmpc_started_ = true;
      }
      const NmpcStep s = nmpc_->Step(in);
      out.nmpc = true;
      plan_time_ = t;
      out.nmpc_thrust = s.u[0];
      out.nmpc_roll = s.u[1];
      out.nmpc_pitch = s.u[2];
      out.solver_time = s.stats.time_total;
      out.sqp_iterations = s.stats.sqp_iterations;
      out.qp_iterations = s.stats.qp_iterations;
      out.fallback = s.stats.fallback;
      out.status = s.stats.status;
      out.reference = s.reference;
      if (out.fallback) ++fallbacks_;
      thrust = s.u[0];
      roll = s.u[1] - applied_offset_[0];
      pitch = s.u[2] - applied_offset_[1];
      Blend(t, &thrust, &roll, &pitch);
      d = ladder_.Update(t, true, out.fallback);
    } else {
      // No estimate to run on: level attitude at hover thrust, damped by the raw
      // motion-capture vertical speed while it is fresh and consistent, until the estimate
      // returns or the ladder's timeout hands over to the failsafe controller. (The last
      // NMPC thrust may belong to a climb or a descent: held, it drops or lifts the vehicle.)
      const double hover = config_.params.mass * kGravity;
      const bool raw = RawMocapFresh(t) && std::isfinite(raw_v_.z()) && !VelocityInconsistent(t);
      thrust = raw ? hover - config_.params.mass * config_.pid.kd_z * raw_v_.z() : hover;
      thrust = std::clamp(thrust, 0.0, config_.pid.max_thrust);
      roll = pitch = 0.0;
      d = ladder_.Update(t, false, false);
    }
    out.recovery = d.action;
    out.recovery_reason = d.reason;
    if (d.action == RecoveryAction::kReinitialise) reinit_pending_ = true;
    if (d.action == RecoveryAction::kFailsafe) EnterFailsafe(t, d.reason);
  }

  if (phase_ == FlightPhase::kFailsafe) {
    // Hold the altitude with the attitude level, then descend; from the height if known,
    // else from the vertical speed, else at a thrust just below hover.
    const double fs = config_.safety.recovery.failsafe_descent_speed;
    const bool descending = t - phase_start_ >= config_.safety.recovery.failsafe_hold_time;
    const double vz_ref = descending ? -fs : 0.0;
    const double hover = config_.params.mass * kGravity;
    const double zf = FailsafeHeight(t);
    const bool raw = RawMocapFresh(t);
    const double vz_meas = raw && std::isfinite(raw_v_.z()) ? raw_v_.z() : own.velocity.z();
    if (std::isfinite(zf)) {
      if (!std::isfinite(z_ref_)) z_ref_ = zf;
      if (descending) z_ref_ = std::max(ground - 0.3, z_ref_ - fs * dt);
      // Level: no horizontal damping (the horizontal estimate may be what failed).
      const double vz = std::isfinite(vz_meas) ? vz_meas : 0.0;
      const PidCommand c = pid_.Update(dt, z_ref_, vz_ref, zf, Vec3(0.0, 0.0, vz), Vec3::Zero(),
                                       Vec<2>::Constant(kNaN));
      thrust = c.thrust;
      if (TouchedDown(t, zf, vz)) {
        phase_ = FlightPhase::kLanded;
        phase_start_ = t;
        thrust = 0.0;
      }
    } else if (std::isfinite(vz_meas) && !VelocityInconsistent(t)) {
      thrust = hover + config_.params.mass * config_.pid.kd_z * (vz_ref - vz_meas);
    } else {
      thrust = descending ? kFailsafeBlindThrustFactor * hover : hover;
    }
    roll = pitch = 0.0;
    if (raw && raw_v_.allFinite() && std::isfinite(raw_yaw_)) {
      // Motion capture left: brake the horizontal velocity too (the PID's damping).
      const PidCommand c =
          pid_.Update(0.0, zf, 0.0, zf, raw_v_, Vec3(0.0, 0.0, raw_yaw_), Vec<2>::Constant(kNaN));
      roll = c.roll;
      pitch = c.pitch;
    }
    thrust = std::clamp(thrust, 0.0, config_.pid.max_thrust);
  }

  // ---- Guard: a non-finite estimate or solution never becomes a command.
  if (!std::isfinite(thrust) || !std::isfinite(roll) || !std::isfinite(pitch)) {
    out.guarded = true;
    if (last_command_.allFinite()) {
      thrust = last_command_[0];
      roll = last_command_[1];
      pitch = last_command_[2];
    } else {
      thrust = roll = pitch = 0.0;
    }
  } else {
    last_command_ = Vec3(thrust, roll, pitch);
    const double a = config_.blend_time > 0.0 ? 1.0 - std::exp(-dt / config_.blend_time) : 1.0;
    mean_thrust_ =
        std::isfinite(mean_thrust_) ? mean_thrust_ + a * (thrust - mean_thrust_) : thrust;
  }
  if (phase_ == FlightPhase::kNmpc) attitude_offset_.Sent(Vec<2>(roll, pitch));
  out.phase = phase_;
  out.thrust = thrust;
  out.roll = roll;
  out.pitch = pitch;
  if (config_.use_throttle && std::isfinite(voltage_)) {
    out.throttle = ThrustToThrottle(config_.params.throttle, thrust, voltage_);
  }
  return out;
}

}  // namespace fnmpc::formation

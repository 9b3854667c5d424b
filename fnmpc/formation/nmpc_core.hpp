// SPDX-License-Identifier: BSD-3-Clause
#pragma once
// The NMPC cores of the vehicle controller (internal to fnmpc_formation): one step's inputs
// (NmpcInput), the core interface (NmpcCore) and its leader and reduced-follower
// implementations (nmpc_core.cpp). VehicleController builds one and feeds it its estimates.

#include <array>
#include <memory>
#include <vector>

#include "fnmpc/core/types.hpp"
#include "fnmpc/formation/neighbour_plan.hpp"
#include "fnmpc/formation/neighbour_thrust.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/rti/rti_solver.hpp"

namespace fnmpc::formation {

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
WakeSlots WakeSources(const std::array<bool, kMaxNeighbours>& active, int count);

/// Thrust [N] a follower assumes for a neighbour whose wake it predicts, from its estimated
/// acceleration (the filter's mixed mean: zero in the hover mode) and the own vehicle file's
/// mass, bounded to what any vehicle of the formation can be commanded (neighbour_thrust.hpp);
/// cooperative mode uses the shared plan's while it is fresh.
ThrustEstimate NeighbourThrust(const ControllerConfig& c, const Vec3& acc);

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
Vec3 ObstacleAt(const NmpcInput& in, int o, double t);

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

/// The leader's core (absolute position, waypoint reference) and the reduced follower's
/// (neighbour-relative formation cost), built with their solvers (no allocation later).
std::unique_ptr<NmpcCore> MakeLeaderCore(const ControllerConfig& c);
std::unique_ptr<NmpcCore> MakeFollowerCore(const ControllerConfig& c);

}  // namespace fnmpc::formation

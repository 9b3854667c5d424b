// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>
#include <cstdint>
#include <string_view>

#include "fnmpc/core/held_for.hpp"
#include "fnmpc/core/serialize.hpp"

/// The NMPC's recovery ladder, after PX4's failsafe state machine: explicit states and
/// transitions, each with a reason, decided from per-step facts only (no solver, no
/// estimator inside), so that it is tested on its own.
///
///   nominal --K consecutive fallbacks--> re-initialise (solver restarted from the current
///   estimate, iterated to convergence as at its first call) --success--> nominal
///   re-initialise --K more fallbacks, max_reinitialisations used--> failsafe
///   any --estimate unusable for estimate_timeout--> failsafe
///   failsafe: hold the altitude with the attitude level for failsafe_hold_time, then
///   descend at failsafe_descent_speed and stop the motors on touchdown (terminal).
namespace fnmpc::formation {

/// Settings of the recovery ladder and the failsafe controller.
struct RecoveryConfig {
  int fallbacks_before_reinit = 3;
  int max_reinitialisations = 2;
  double estimate_timeout = 0.5;
  double failsafe_hold_time = 1.0;
  double failsafe_descent_speed = 0.4;

  /// Every field with its key (scenario block `safety.recovery:`) and meaning.
  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("fallbacks_before_reinit", &fallbacks_before_reinit, IntIn(1, 1000).Quiet(),
             "K consecutive fallbacks re-initialise the solver from the current estimate");
    a->Visit("max_reinitialisations", &max_reinitialisations, IntIn(0, 1000).Quiet(),
             "re-initialisations without a successful step in between before the failsafe");
    a->Visit("estimate_timeout", &estimate_timeout, Positive(),
             "[s] no usable estimate this long hands over to the failsafe");
    a->Visit("failsafe_hold_time", &failsafe_hold_time, NonNegative(),
             "[s] failsafe: level hover at the current height before descending");
    a->Visit("failsafe_descent_speed", &failsafe_descent_speed, Positive().AtMost(1.5, "m/s"),
             "[m/s] failsafe descent rate");
  }

  /// Throws std::invalid_argument naming the field on an invalid value.
  void Validate() const;
};

/// Safety settings of one vehicle's controller (scenario block `safety:`).
struct SafetyConfig {
  double min_altitude = 0.3, max_altitude = 10.0;
  double neighbour_timeout = 1.0;
  double neighbour_reacquire_time = 0.5;
  double neighbour_departure_height = 0.5;
  double neighbour_departure_time = 0.3;
  double collision_radius = 0.45;
  /// Probability with which the obstacle's estimate keeps r_min (chance constraint, see
  /// CollisionSigmas); 0.5: no margin.
  double collision_confidence = 0.95;
  RecoveryConfig recovery;

  /// The fields a scenario sets (block `safety:`), with their meaning; the fault injection
  /// below is set by the `faults:` block.
  template <class Archive>
  void Serialize(Archive* a) {
    a->Visit("min_altitude", &min_altitude, NonNegative(),
             "[m] soft lower bound on the CoM height above the ground plane in the NMPC phase "
             "(leader: its position state; follower: its displacement from the current height)");
    a->Visit("max_altitude", &max_altitude, Positive(),
             "[m] soft upper bound on the same height; above `min_altitude`");
    a->Visit("neighbour_timeout", &neighbour_timeout, Positive(),
             "[s] a follower's neighbour with no accepted relative measurement this long "
             "leaves its cost");
    a->Visit("neighbour_reacquire_time", &neighbour_reacquire_time, NonNegative(),
             "[s] it returns after accepted measurements spanning this long, no gap longer "
             "than this");
    a->Visit("neighbour_departure_height", &neighbour_departure_height, NonNegative(),
             "[m] a follower's neighbour this far below its place relative to the leader (or to "
             "each of at least two other neighbours) for `neighbour_departure_time` has left the "
             "formation and leaves the cost; it returns within half of it for "
             "`neighbour_reacquire_time` (0: off; docs/safety.md)");
    a->Visit("neighbour_departure_time", &neighbour_departure_time, NonNegative(),
             "[s] how long a neighbour must stay that far below before it leaves the cost");
    a->Visit("collision_radius", &collision_radius, NonNegative().AtMost(10, "m"),
             "[m] r_min: soft minimum CoM distance to every vehicle the relative sensor sees, "
             "in the OCP (0: off); default twice the reference vehicle's arm length (0.225 m, "
             "rotor hubs apart: add propeller clearance for side-by-side flight)");
    a->Visit("collision_confidence", &collision_confidence,
             Finite().AtLeast(0.5, "").Below(1.0, ""),
             "chance constraint of the collision avoidance: each predicted vehicle keeps r_min "
             "with this probability under its estimate's Gaussian uncertainty, a margin of "
             "Φ⁻¹(p) σ(t) along the separating normal with σ(t)² from the relative estimate's "
             "covariance at constant velocity (docs/safety.md); 0.5: no margin");
    a->Nested("recovery", &recovery);
  }
  /// Fault injection (scenario `faults.solver_failures`, docs/scenarios.md), off by default:
  /// this fraction of NMPC steps is forced to fall back (no solve; the time-shifted plan's
  /// first control is applied, as on a solver error), drawn by InjectedSolverFailure() from
  /// `injected_failure_seed` without state.
  double injected_failure_rate = 0.0;
  std::uint64_t injected_failure_seed = 0;

  /// Throws std::invalid_argument naming the field on an invalid value.
  void Validate() const;
};

/// The one-sided standard-normal quantile Phi^-1(collision_confidence) [-]: the margin of
/// the collision constraint in standard deviations of the obstacle's predicted position
/// along the separating normal (0 at 0.5).
double CollisionSigmas(const SafetyConfig& s);

/// Whether the NMPC step of `vehicle` at time t [s] (sample time ts [s]) is a forced
/// fallback: a counter-based draw (splitmix64 of seed, vehicle and step index), so the
/// controller needs no random state and `fnmpc run` can count the injections; never
/// allocates. False whenever injected_failure_rate is 0.
inline bool InjectedSolverFailure(const SafetyConfig& s, int vehicle, double t, double ts) {
  if (!(s.injected_failure_rate > 0.0) || !(ts > 0.0) || !std::isfinite(t)) return false;
  std::uint64_t x = s.injected_failure_seed * 0x9E3779B97F4A7C15ull;
  x ^= (static_cast<std::uint64_t>(vehicle) + 1) << 40;
  x ^= static_cast<std::uint64_t>(std::llround(t / ts));
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  x ^= x >> 31;
  return static_cast<double>(x >> 11) * 0x1.0p-53 < s.injected_failure_rate;
}

/// What the ladder asks the controller to do this step, or (kShiftLandingSite) what the
/// landing did: the safety transitions of the CSV column `recovery`.
enum class RecoveryAction : int {
  kNone = 0,          ///< keep flying the NMPC
  kReinitialise = 1,  ///< restart the solver from the current estimate
  kFailsafe = 2,      ///< hand over to the failsafe controller (terminal)
  /// Landing: the landing site was moved clear of a sensed vehicle below (docs/safety.md
  /// "Landing clear of other vehicles"); not the ladder's, it never changes the ladder state.
  kShiftLandingSite = 3,
  /// Follower: no formation tie leads to the leader any more (TieLoss, formation_ties.hpp);
  /// it lands where it is with the PID landing (docs/safety.md). Not the ladder's either.
  kLand = 4,
};

/// Why the ladder acted.
enum class RecoveryReason : int {
  kNone = 0,
  kConsecutiveFallbacks = 1,  ///< K fallbacks in a row
  kReinitFailed = 2,          ///< fallbacks persisted after max_reinitialisations
  kEstimateUnusable = 3,      ///< no usable estimate for estimate_timeout
  kCommanded = 4,             ///< requested from outside (fault injection, operator)
  kVehicleBelow = 5,          ///< a sensed vehicle within r_min of the landing site, below
  kLeaderDown = 6,            ///< the leader landed or left the formation (TieLoss)
  kNeighboursGone = 7,        ///< every formation neighbour landed or left it (TieLoss)
  kNoNeighbourSeen = 8,       ///< a follower's take-off ended with no neighbour ever sensed
};
std::string_view ToString(RecoveryAction a);
std::string_view ToString(RecoveryReason r);

struct RecoveryDecision {
  RecoveryAction action = RecoveryAction::kNone;
  RecoveryReason reason = RecoveryReason::kNone;
};

/// The ladder's state: call Update() once per NMPC step.
class RecoveryLadder {
 public:
  explicit RecoveryLadder(const RecoveryConfig& config);
  /// Facts of one step at time t [s]: whether the estimate was usable (the NMPC ran on it)
  /// and, if it ran, whether the solver fell back to the shifted plan.
  RecoveryDecision Update(double t, bool estimate_usable, bool fallback);
  /// Forces the failsafe (terminal).
  RecoveryDecision Trigger(RecoveryReason reason);
  [[nodiscard]] bool failsafe() const { return failsafe_; }
  [[nodiscard]] int consecutive_fallbacks() const { return consecutive_fallbacks_; }
  [[nodiscard]] long reinitialisations() const { return reinitialisations_; }

 private:
  RecoveryConfig config_;
  int consecutive_fallbacks_ = 0;
  int reinits_since_success_ = 0;
  long reinitialisations_ = 0;
  HeldFor unusable_;  // the estimate unusable since
  bool failsafe_ = false;
};

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>
#include <cstdint>
#include <string_view>

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
  int fallbacks_before_reinit = 3;      ///< K: consecutive fallbacks that trigger a re-init
  int max_reinitialisations = 2;        ///< re-inits without a success in between, then failsafe
  double estimate_timeout = 0.5;        ///< T: estimate unusable this long -> failsafe [s]
  double failsafe_hold_time = 1.0;      ///< level hover at the failsafe altitude [s]
  double failsafe_descent_speed = 0.4;  ///< failsafe descent rate [m/s]

  /// Throws std::invalid_argument naming the field on an invalid value.
  void Validate() const;
};

/// Safety settings of one vehicle's controller (scenario block `safety:`).
struct SafetyConfig {
  /// Soft bounds on the height of the CoM above the ground plane in the NMPC phase [m]
  /// (leader: its position state; follower: its displacement from the current height).
  double min_altitude = 0.3, max_altitude = 10.0;
  /// A follower's neighbour with no accepted relative measurement for this long leaves the
  /// cost [s]; it returns after measurements were accepted for `neighbour_reacquire_time`
  /// with no gap longer than that.
  double neighbour_timeout = 1.0;
  double neighbour_reacquire_time = 0.5;
  /// Minimum CoM distance kept to every sensed vehicle (soft constraint in the OCP) [m]:
  /// twice the reference vehicle's arm length (0.225 m), rotor hubs apart. 0: off.
  double collision_radius = 0.45;
  RecoveryConfig recovery;
  /// Fault injection (scenario `faults.solver_failures`, docs/scenarios.md), off by default:
  /// this fraction of NMPC steps is forced to fall back (no solve; the time-shifted plan's
  /// first control is applied, as on a solver error), drawn by InjectedSolverFailure() from
  /// `injected_failure_seed` without state.
  double injected_failure_rate = 0.0;
  std::uint64_t injected_failure_seed = 0;

  /// Throws std::invalid_argument naming the field on an invalid value.
  void Validate() const;
};

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

/// What the ladder asks the controller to do this step.
enum class RecoveryAction : int {
  kNone = 0,          ///< keep flying the NMPC
  kReinitialise = 1,  ///< restart the solver from the current estimate
  kFailsafe = 2,      ///< hand over to the failsafe controller (terminal)
};

/// Why the ladder acted.
enum class RecoveryReason : int {
  kNone = 0,
  kConsecutiveFallbacks = 1,  ///< K fallbacks in a row
  kReinitFailed = 2,          ///< fallbacks persisted after max_reinitialisations
  kEstimateUnusable = 3,      ///< no usable estimate for estimate_timeout
  kCommanded = 4,             ///< requested from outside (fault injection, operator)
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
  double unusable_since_ = -1.0;  // < 0: estimate usable
  bool failsafe_ = false;
};

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/recovery.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "fnmpc/estimation/ekf_math.hpp"

namespace fnmpc::formation {

void RecoveryConfig::Validate() const {
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("[RecoveryConfig] " + what);
  };
  if (fallbacks_before_reinit < 1) fail("fallbacks_before_reinit must be >= 1");
  if (max_reinitialisations < 0) fail("max_reinitialisations must be >= 0");
  if (!(estimate_timeout > 0.0) || !std::isfinite(estimate_timeout))
    fail("estimate_timeout must be > 0 and finite");
  if (!(failsafe_hold_time >= 0.0) || !std::isfinite(failsafe_hold_time))
    fail("failsafe_hold_time must be >= 0 and finite");
  if (!(failsafe_descent_speed > 0.0 && failsafe_descent_speed <= 1.5))
    fail("failsafe_descent_speed must be in (0, 1.5] m/s");
}

void SafetyConfig::Validate() const {
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("[SafetyConfig] " + what);
  };
  if (!(min_altitude >= 0.0 && max_altitude > min_altitude) || !std::isfinite(max_altitude))
    fail("altitude bounds need 0 <= min_altitude < max_altitude (finite)");
  if (!(neighbour_timeout > 0.0) || !std::isfinite(neighbour_timeout))
    fail("neighbour_timeout must be > 0 and finite");
  if (!(neighbour_reacquire_time >= 0.0) || !std::isfinite(neighbour_reacquire_time))
    fail("neighbour_reacquire_time must be >= 0 and finite");
  if (!(neighbour_departure_height >= 0.0) || !std::isfinite(neighbour_departure_height))
    fail("neighbour_departure_height must be >= 0 and finite");
  if (!(neighbour_departure_time >= 0.0) || !std::isfinite(neighbour_departure_time))
    fail("neighbour_departure_time must be >= 0 and finite");
  if (!(collision_radius >= 0.0 && collision_radius <= 10.0))
    fail("collision_radius must be in [0, 10] m");
  if (!(collision_confidence >= 0.5 && collision_confidence < 1.0))
    fail("collision_confidence must be in [0.5, 1)");
  if (!(injected_failure_rate >= 0.0 && injected_failure_rate <= 1.0))
    fail("injected_failure_rate must be in [0, 1]");
  recovery.Validate();
}

// P(Z <= k) = p for a standard normal Z and k >= 0 is P(Z^2 <= k^2) = 2p - 1: the
// chi-square(1) quantile of 2p - 1.
double CollisionSigmas(const SafetyConfig& s) {
  const double p = 2.0 * s.collision_confidence - 1.0;
  return p > 0.0 ? std::sqrt(estimation::Chi2Quantile(p, 1)) : 0.0;
}

std::string_view ToString(RecoveryAction a) {
  switch (a) {
    case RecoveryAction::kNone:
      return "none";
    case RecoveryAction::kReinitialise:
      return "reinitialise";
    case RecoveryAction::kFailsafe:
      return "failsafe";
    case RecoveryAction::kShiftLandingSite:
      return "shift_landing_site";
    case RecoveryAction::kLand:
      return "land";
  }
  return "?";
}

std::string_view ToString(RecoveryReason r) {
  switch (r) {
    case RecoveryReason::kNone:
      return "none";
    case RecoveryReason::kConsecutiveFallbacks:
      return "consecutive_fallbacks";
    case RecoveryReason::kReinitFailed:
      return "reinitialisation_failed";
    case RecoveryReason::kEstimateUnusable:
      return "estimate_unusable";
    case RecoveryReason::kCommanded:
      return "commanded";
    case RecoveryReason::kVehicleBelow:
      return "vehicle_below";
    case RecoveryReason::kLeaderDown:
      return "leader_down";
    case RecoveryReason::kNeighboursGone:
      return "neighbours_gone";
    case RecoveryReason::kNoNeighbourSeen:
      return "no_neighbour_seen";
  }
  return "?";
}

RecoveryLadder::RecoveryLadder(const RecoveryConfig& config) : config_(config) {
  config_.Validate();
}

RecoveryDecision RecoveryLadder::Trigger(RecoveryReason reason) {
  failsafe_ = true;
  return {RecoveryAction::kFailsafe, reason};
}

RecoveryDecision RecoveryLadder::Update(double t, bool estimate_usable, bool fallback) {
  if (failsafe_) return {};
  if (!estimate_usable) {
    // A re-initialisation needs an estimate: only the timer runs.
    unusable_.Start(t);
    if (unusable_.For(t, config_.estimate_timeout))
      return Trigger(RecoveryReason::kEstimateUnusable);
    return {};
  }
  unusable_.Reset();
  if (!fallback) {
    consecutive_fallbacks_ = 0;
    reinits_since_success_ = 0;
    return {};
  }
  if (++consecutive_fallbacks_ < config_.fallbacks_before_reinit) return {};
  consecutive_fallbacks_ = 0;
  if (reinits_since_success_ >= config_.max_reinitialisations)
    return Trigger(RecoveryReason::kReinitFailed);
  ++reinits_since_success_;
  ++reinitialisations_;
  return {RecoveryAction::kReinitialise, RecoveryReason::kConsecutiveFallbacks};
}

}  // namespace fnmpc::formation

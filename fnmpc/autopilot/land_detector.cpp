// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/autopilot/land_detector.hpp"

#include <cmath>
#include <limits>
#include <numbers>

namespace fnmpc::autopilot {
namespace {

// PX4 MulticopterLandDetector.h trigger times [s].
constexpr double kGroundContactTrigger = 0.35;
constexpr double kMaybeLandedTrigger = 0.25;
constexpr double kLandedTrigger = 0.30;
// ArduCopter config.h.
constexpr double kArduLandTrigger = 1.0;     // LAND_DETECTOR_TRIGGER_SEC
constexpr double kArduAccelMax = 1.0;        // LAND_DETECTOR_ACCEL_MAX [m/s^2]
constexpr double kArduAccelCutoffHz = 1.0;   // LAND_DETECTOR_ACCEL_LPF_CUTOFF
constexpr double kArduDescentRateMax = 1.0;  // land_detector.cpp descent_rate_low [m/s]

}  // namespace

void LandDetector::Hysteresis::Update(double now, bool condition, double trigger) {
  if (!condition) {
    since = kNaN;
    state = false;
    return;
  }
  if (std::isnan(since)) since = now;
  state = now - since >= trigger - 1e-9;
}

LandDetector::LandDetector(AutopilotKind kind, const LandDetectorSettings& settings)
    : kind_(kind), settings_(settings) {
  CheckLimits(settings_, "LandDetectorSettings");
  Reset(0.0);
}

void LandDetector::Reset(double now) {
  const Hysteresis held{-std::numeric_limits<double>::infinity(), true};
  ground_contact_ = maybe_landed_ = landed_stage_ = land_complete_ = held;
  landed_ = true;
  taken_off_ = false;
  armed_at_ = now;
  landed_since_ = now;
  filtered_accel_ = 0.0;
  last_time_ = kNaN;
}

void LandDetector::Update(double now, const LandDetectorInput& in) {
  const bool thrust_known = std::isfinite(in.thrust);
  if (kind_ == AutopilotKind::kPx4) {
    const LandDetectorSettings& s = settings_;
    const double low_thrust = s.thr_min + (s.thr_hover - s.thr_min) * 0.3;
    ground_contact_.Update(now,
                           thrust_known && in.thrust <= low_thrust &&
                               std::abs(in.vertical_speed) <= s.z_vel_max &&
                               in.horizontal_speed <= s.xy_vel_max,
                           kGroundContactTrigger);
    const double rot_max = s.rot_max_deg * std::numbers::pi / 180.0;
    maybe_landed_.Update(
        now, ground_contact_.state && in.thrust <= s.manthr_min + 0.01 && in.tilt_rate <= rot_max,
        kMaybeLandedTrigger);
    landed_stage_.Update(now, maybe_landed_.state, kLandedTrigger);
    landed_ = landed_stage_.state;
  } else {
    // First-order low-pass of the acceleration at 1 Hz, as ArduCopter's land_accel_ef_filter.
    const double dt = std::isfinite(last_time_) ? now - last_time_ : 0.0;
    const double rc = 1.0 / (2.0 * std::numbers::pi * kArduAccelCutoffHz);
    filtered_accel_ += (dt / (dt + rc)) * (in.acceleration - filtered_accel_);
    land_complete_.Update(now,
                          thrust_known && in.thrust <= settings_.lower_limit_thrust &&
                              filtered_accel_ <= kArduAccelMax &&
                              std::abs(in.vertical_speed) < kArduDescentRateMax,
                          kArduLandTrigger);
    landed_ = land_complete_.state;
  }
  last_time_ = now;
  if (!landed_) {
    taken_off_ = true;
    landed_since_ = kNaN;
  } else if (std::isnan(landed_since_)) {
    landed_since_ = now;
  }
}

bool LandDetector::disarm_allowed() const {
  return kind_ == AutopilotKind::kPx4 ? landed_ || maybe_landed_.state : landed_;
}

bool LandDetector::auto_disarm_due(double now) const {
  if (kind_ != AutopilotKind::kPx4 || !landed_) return false;
  if (taken_off_) {
    return settings_.disarm_land > 0.0 && now - landed_since_ >= settings_.disarm_land - 1e-9;
  }
  return settings_.disarm_preflight > 0.0 && now - armed_at_ >= settings_.disarm_preflight - 1e-9;
}

}  // namespace fnmpc::autopilot

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include "fnmpc/core/sensors.hpp"

/// Status codes, flight modes and rejection counters shared by the estimators.
namespace fnmpc::estimation {

/// Outcome of processing one measurement or command. Never thrown: the caller logs it.
enum class EkfStatus : int {
  kAccepted = 0,           ///< fused (or used as an input)
  kIgnored = 1,            ///< valid but not used by this filter in the current mode
  kRejectedNonFinite = 2,  ///< a used field was NaN or infinite (or the stamp was)
  kRejectedGated = 3,      ///< Mahalanobis distance above the gate (outlier)
  kRejectedTooOld = 4,     ///< stamp older than the replay lag (or than the buffer)
  kRejectedInvalid = 5,    ///< wrong vehicle/target, disabled sensor or implausible value
  kNotInitialized = 6,     ///< arrived before the filter was initialised
  kNumericalError = 7,     ///< the update produced a non-finite state or covariance
  kRejectedTimeJump = 8,   ///< stamp further ahead of the filter time than `max_time_jump`
};
inline constexpr int kNumEkfStatus = 9;

/// Name of a status for logs ("accepted", "gated", ...).
std::string_view ToString(EkfStatus s);

/// Flight mode of the vehicle filter (multi-modal EKF).
enum class VehicleMode : int {
  kLanded = 0,  ///< no motion: p, v held (zero-velocity updates), attitude from IMU + compass
  kFlying = 1,  ///< motion model driven by the IMU or by the command
};

/// Name of a mode for logs ("landed", "flying").
std::string_view ToString(VehicleMode m);

/// Reasons why an estimate must not be used, as bits of EstimateHealth::flags.
enum class HealthFlag : std::uint32_t {
  kNotInitialized = 1u << 0,      ///< no state yet
  kNonFinite = 1u << 1,           ///< query time, state or covariance not finite
  kPositionUncertain = 1u << 2,   ///< position std above `max_position_std`
  kVelocityUncertain = 1u << 3,   ///< velocity std above `max_velocity_std`
  kAttitudeUncertain = 1u << 4,   ///< attitude (neighbour: yaw) std above its limit
  kAttitudeEnvelope = 1u << 5,    ///< |pitch| above `max_pitch` (Euler-rate singularity guard)
  kStale = 1u << 6,               ///< a monitored measurement kind is stale (see stale_kinds)
  kExtrapolationLimit = 1u << 7,  ///< query time beyond newest event + `max_extrapolation`
};
inline constexpr int kNumHealthFlags = 8;

/// Name of one flag for logs ("stale", "position_uncertain", ...).
std::string_view ToString(HealthFlag f);

/// Health of one estimate: why it is not valid, and the figures behind the decision.
/// `flags == 0` is exactly `valid == true` in the estimate that carries it.
struct EstimateHealth {
  std::uint32_t flags = static_cast<std::uint32_t>(HealthFlag::kNotInitialized);
  /// Bit k set: SensorKind k is monitored and stale (its staleness is above its limit).
  std::uint32_t stale_kinds = 0;
  /// Query time minus the stamp of the newest fused measurement of each kind [s]; kInf
  /// when none was fused since initialisation.
  std::array<double, kNumSensorKinds> staleness{kInf, kInf, kInf, kInf, kInf, kInf};
  double position_std = kNaN;   ///< largest position (neighbour: dx) std over the axes [m]
  double velocity_std = kNaN;   ///< largest velocity std over the axes [m/s]
  double attitude_std = kNaN;   ///< largest Euler-angle std (neighbour: yaw std) [rad]
  double extrapolation = kNaN;  ///< query time minus the newest event's stamp [s]

  [[nodiscard]] bool ok() const { return flags == 0; }
  [[nodiscard]] bool Has(HealthFlag f) const {
    return (flags & static_cast<std::uint32_t>(f)) != 0;
  }
  [[nodiscard]] bool IsStale(SensorKind k) const {
    return (stale_kinds & (1u << static_cast<unsigned>(k))) != 0;
  }
  void Set(HealthFlag f) { flags |= static_cast<std::uint32_t>(f); }
};

/// Per-reason, per-sensor-kind counters. Every processed measurement increments exactly one
/// entry of `by_status` (index = EkfStatus, then SensorKind); a replay that changes the
/// outcome of an already counted measurement moves its count, so the counters always equal
/// those of in-order delivery. Commands and own-velocity samples are counted separately.
struct EkfCounters {
  /// by_status[status][kind]: number of measurements of `kind` that ended with `status`.
  std::array<std::array<std::int64_t, kNumSensorKinds>, kNumEkfStatus> by_status{};
  std::int64_t commands = 0;           ///< accepted commands / own-velocity samples
  std::int64_t commands_rejected = 0;  ///< non-finite or too old commands / velocity samples
  std::int64_t replays = 0;            ///< out-of-order insertions that triggered a replay
  std::int64_t buffer_overflows = 0;   ///< oldest buffer entries evicted because it was full
  std::int64_t gate_resets = 0;        ///< covariance re-inflations after repeated gating
  std::int64_t mode_switches = 0;      ///< landed <-> flying transitions
  std::int64_t time_resets = 0;        ///< re-anchors after repeated forward time jumps

  /// Count for one status and kind.
  [[nodiscard]] std::int64_t Get(EkfStatus s, SensorKind k) const {
    return by_status[static_cast<int>(s)][static_cast<int>(k)];
  }
  /// Count for one status over all kinds.
  [[nodiscard]] std::int64_t Total(EkfStatus s) const {
    std::int64_t n = 0;
    for (auto v : by_status[static_cast<int>(s)]) n += v;
    return n;
  }
  /// Moves one count of kind `k` from status `from` to status `to` (replay bookkeeping).
  void Move(SensorKind k, EkfStatus from, EkfStatus to) {
    --by_status[static_cast<int>(from)][static_cast<int>(k)];
    ++by_status[static_cast<int>(to)][static_cast<int>(k)];
  }
  /// Adds one count.
  void Add(SensorKind k, EkfStatus s) { ++by_status[static_cast<int>(s)][static_cast<int>(k)]; }
};

}  // namespace fnmpc::estimation

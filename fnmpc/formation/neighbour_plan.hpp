// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <vector>

#include "fnmpc/core/types.hpp"

/// Cooperative mode (Compensation::kCooperative): every vehicle publishes, every
/// control step, the trajectory its NMPC predicts and its disturbance estimate; a follower
/// predicts a neighbour along that plan, anchored at its own relative estimate, instead of at
/// constant velocity while the plan is fresh. Fixed-size storage: receiving and predicting
/// never allocate (the control step's no-allocation guarantee).
namespace fnmpc::formation {

/// Most shooting intervals a plan carries (the largest `controller.horizon`).
inline constexpr int kMaxPlanIntervals = 100;

/// One vehicle's plan, as published after its control step at `stamp`. Frame-free: the
/// positions are displacements from the vehicle's own position at `stamp`, in world-aligned
/// axes ({n}, which the followers' {m} shares): a follower that knows a neighbour only by its
/// relative position can use it without a common origin.
struct PlanMessage {
  int vehicle = -1;           ///< publisher (scenario vehicle index)
  double stamp = kNaN;        ///< time of the control step that made the plan [s]
  double sample_time = kNaN;  ///< interval between points [s]
  int points = 0;             ///< valid entries below: horizon + 1 (2..kMaxPlanIntervals + 1)
  std::array<Vec3, kMaxPlanIntervals + 1> displacement{};  ///< p(stamp + k Ts) - p(stamp) [m]
  std::array<Vec3, kMaxPlanIntervals + 1> velocity{};      ///< predicted velocity [m/s]
  std::array<double, kMaxPlanIntervals + 1> thrust{};      ///< planned collective thrust [N]
  /// The publisher's external acceleration at `stamp` ({n} axes) [m/s^2]: what its own NMPC
  /// predicted with (estimator's d plus its wake model's part; zero with Compensation::kNone).
  Vec3 disturbance = Vec3::Zero();

  /// Finite fields, points in range, sample_time > 0.
  [[nodiscard]] bool Valid() const;
  /// Size on the link [bytes]: a 32-byte header (vehicle, points, stamp, sample time, as
  /// int32/int32/double/double, plus the disturbance as 3 float32 and padding) and 7 float32
  /// per point (displacement, velocity, thrust). The simulated link's bandwidth uses it.
  [[nodiscard]] int WireBytes() const { return 32 + 28 * points; }
};

/// What a plan says about its publisher `tau` after the receiver's time t.
struct PlanPrediction {
  Vec3 rel = Vec3::Zero();  ///< relative position p_j - p_self(t), anchored (see Predict)
  Vec3 vel = Vec3::Zero();  ///< the publisher's velocity, anchored likewise [m/s]
  double thrust = kNaN;     ///< its planned thrust [N]
};

/// The latest plan of each of a follower's formation neighbours (configuration order).
class NeighbourPlans {
 public:
  /// `vehicles[j]`: the publisher neighbour slot j listens to. Allocates (construction only).
  explicit NeighbourPlans(const std::vector<int>& vehicles = {});

  /// Stores `m` in the slot of its publisher when it is valid and newer than the stored
  /// plan; returns whether it was stored. No allocation.
  bool Receive(const PlanMessage& m);
  /// Whether slot j holds a plan no older than max_age at time t (age = t - stamp; a plan
  /// stamped after t, clock skew, counts as age 0).
  [[nodiscard]] bool Fresh(int j, double t, double max_age) const;
  /// Neighbour j at t + tau from its plan, if Fresh: the plan's displacement between now
  /// (age a = t - stamp) and a + tau added to `rel_now`, the receiver's own current estimate
  /// of p_j - p_self (the anchor: the plan's absolute origin is never needed), and the plan's
  /// change of velocity over the same interval added to `vel_now`, the receiver's estimate of
  /// the neighbour's velocity: the relative velocity stays in the receiver's own estimation
  /// frame (a bias of either vehicle's own velocity estimate would otherwise become a drift of
  /// followers that see only each other), with the plan's thrust there. Linear interpolation
  /// between the plan's points; beyond its last point, constant velocity from there. Returns
  /// false (and leaves *out) when there is no fresh plan: the caller falls back.
  bool Predict(int j, double t, double tau, double max_age, const Vec3& rel_now,
               const Vec3& vel_now, PlanPrediction* out) const;
  /// The stored plan of slot j (stamp NaN: none yet).
  [[nodiscard]] const PlanMessage& plan(int j) const { return plans_.at(j); }
  [[nodiscard]] int slots() const { return static_cast<int>(plans_.size()); }
  /// Forgets every plan (a restart).
  void Clear();

 private:
  std::vector<int> vehicles_;
  std::vector<PlanMessage> plans_;
};

}  // namespace fnmpc::formation

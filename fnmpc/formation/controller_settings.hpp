// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/core/serialize.hpp"
#include "fnmpc/formation/recovery.hpp"
#include "fnmpc/formation/tie_weights.hpp"
#include "fnmpc/rti/rti_settings.hpp"

namespace fnmpc::formation {

/// How much of the aerodynamic interaction the NMPC compensates (the levels compared in
/// docs/results.md "Beating the wake"; each includes the ones before it).
enum class Compensation : int {
  kNone = 0,         ///< the reference work's controller: no disturbance in the prediction
  kObserver = 1,     ///< the own estimator's external acceleration d as a stage parameter
  kWake = 2,         ///< plus the neighbours' predicted wakes (follower; model::WakeForceModel)
  kCooperative = 3,  ///< plus the neighbours' shared plans (NeighbourPlans) while they are fresh
};
inline constexpr const char* kCompensationNames[] = {"none", "observer", "wake", "cooperative"};
/// The names of Compensation, all implemented.
inline constexpr Choice kCompensationChoice{kCompensationNames, 4, 4};
inline const char* ToString(Compensation c) { return kCompensationNames[static_cast<int>(c)]; }

/// The settings every vehicle's controller of a formation shares: what a scenario sets
/// (blocks `controller:`, `phases:`, `safety:` and `leader.start_time`). Serialize lists each
/// field once with its key, accepted values and meaning; the defaults are the initialisers.
struct ControllerSettings {
  rti::RtiSettings rti;  ///< Ts, N, iterations, budget, QP (defaults: the reference work)
  double thrust_min = 5.0, thrust_max = 25.0;
  double max_attitude_ref = 0.35;
  double max_speed = 2.0;
  SafetyConfig safety;
  double trajectory_start = 10.0;
  double takeoff_time = 1.0;
  double takeoff_height = 1.0;
  double climb_speed = 0.5;
  double hover_before_switch = 1.5;
  double blend_time = 0.5;
  double landing_time = 1e9;
  double descent_speed = 0.3;
  bool use_throttle = true;
  /// Most vehicles one controller tracks with a relative-sensor filter at once.
  int max_tracked = 8;
  Compensation compensation = Compensation::kNone;
  /// Follower: decay time of a neighbour's estimated acceleration in its prediction [s]
  /// (neighbour_acceleration.hpp); 0: constant-velocity prediction (the reference work).
  double neighbour_acceleration_decay = 0.0;
  /// Follower: low-pass time constant of that estimate (the neighbour velocity's derivative) [s].
  double neighbour_acceleration_filter = 0.1;
  /// Cooperative mode: a neighbour's plan older than this is not used [s].
  double plan_timeout = 0.2;
  /// Offset-free attitude (Compensation::kObserver on; attitude_offset.hpp): low-pass time
  /// constant of the attitude offset estimate [s] and its bound [rad].
  double attitude_offset_filter = 2.0;
  double attitude_offset_max = 0.07;
  /// Follower: how its tie weight is shared among its neighbours (tie_weights.hpp).
  TieWeighting tie_weights = TieWeighting::kEqual;
  /// Follower: scale of the discount of a tie that disagrees with the ties towards the
  /// leader [m] (DiscountDisagreeingTies); 0: off.
  double tie_disagreement = 0.25;

  template <class Archive>
  void Serialize(Archive* a) {
    a->Nested("controller", &rti);
    a->Visit("controller.max_tracked", &max_tracked, IntIn(1, 64),
             "tracking slots per controller (relative-sensor filters, allocated at start): "
             "formation neighbours always have one, the other vehicles in view share the "
             "rest nearest first (collision avoidance); a slot is freed after "
             "`safety.neighbour_timeout` without a measurement of its vehicle");
    a->VisitChoice("controller.compensation", &compensation, kCompensationChoice,
                   "disturbance compensation: none = the reference work's NMPC; observer = the "
                   "own estimator's external acceleration (VehicleEkf state d) enters the "
                   "prediction as a constant stage parameter (offset-free NMPC); wake = observer "
                   "plus, in a follower's prediction, the wakes of its first 4 active formation "
                   "neighbours at their predicted relative positions and thrusts estimated from "
                   "their motion, m ‖a + g e_z‖ with the own vehicle file's mass m (smooth "
                   "round-jet model, docs/safety.md), the observer's d then carrying only the "
                   "rest; cooperative = wake plus, in a follower's prediction of a neighbour, the "
                   "plan that neighbour published (predicted trajectory and thrust) while it is "
                   "fresh, else constant velocity (docs/scenarios.md, block `link:`). "
                   "`fnmpc run --compensation` overrides it");
    a->Visit("controller.plan_timeout", &plan_timeout, Positive(),
             "[s] cooperative: a neighbour's plan older than this (time since the control step "
             "that made it) is late and not used; the neighbour is then predicted at constant "
             "velocity");
    a->Visit("controller.attitude_offset.filter_time", &attitude_offset_filter, Positive(),
             "[s] observer level and above: low-pass time constant of the estimate of the "
             "constant roll and pitch offset by which the vehicle's attitude misses the NMPC's "
             "model (an autopilot's level-calibration bias: it settles at k ref + offset), from "
             "the measured attitude and the references sent through the model's first-order "
             "attitude map; the reference sent is the NMPC's minus offset / k (docs/scenarios.md "
             "\"Compensation\")");
    a->Visit("controller.attitude_offset.max", &attitude_offset_max, NonNegative(),
             "[rad] bound of that estimate per axis (below `bounds.attitude_ref`); a cut "
             "estimate is counted in summary.json (`attitude_offset_bounded`, steps). The NMPC's "
             "reference bounds move with the correction, so the reference sent stays within "
             "`bounds.attitude_ref` unclamped");
    a->VisitChoice("controller.tie_weights", &tie_weights, kTieWeightingChoice,
                   "follower: how its formation-tie weight (the active ties' count times "
                   "`weights.follower`) is shared among its neighbours, by their graph depth "
                   "(fewest ties from the leader, computed from the formation's ties): equal = "
                   "alike (the reference work); depth = only the ties to the neighbours of the "
                   "lowest depth among the active ones (the row ahead; a row-mate's tie then "
                   "carries weight only when no tie towards the leader is left). String "
                   "stability down the graph, docs/results.md \"Scale\"");
    a->Visit("controller.tie_disagreement", &tie_disagreement, NonNegative(),
             "[m] follower: every control step, a tie to a neighbour deeper than its shallowest "
             "active neighbours (nearest the leader) is weighted by 1 / (1 + (e / "
             "tie_disagreement)^2) on top of `tie_weights`, e the distance between the place "
             "that tie asks for (the neighbour's estimate minus the desired offset) and the "
             "place the shallowest ties ask for; the weights still sum to the active count, and "
             "e per axis widens that neighbour's `relative_position_bound`. A neighbour leaving "
             "its place (a dead controller, docs/safety.md) then stops pulling the follower "
             "before it is dropped; 0 = off");
    a->Visit("controller.neighbour_acceleration.decay", &neighbour_acceleration_decay,
             NonNegative(),
             "[s] follower: each formation neighbour is predicted with its estimated acceleration "
             "(the filtered derivative of its estimated velocity, times the neighbour filter's "
             "manoeuvre-mode probability) decaying as exp(-t / decay) over the horizon "
             "(Singer's manoeuvre model; string stability down the graph, docs/results.md "
             "\"Scale\"); 0 = constant-velocity prediction (the reference work)");
    a->Visit("controller.neighbour_acceleration.filter_time", &neighbour_acceleration_filter,
             NonNegative(),
             "[s] follower: first-order low-pass time constant of the neighbour acceleration "
             "estimate");
    a->Visit("controller.use_throttle", &use_throttle, AnyValue(),
             "true: command the collective throttle from the thrust and the measured battery "
             "voltage; false: the thrust");
    a->VisitRange("controller.bounds.thrust", &thrust_min, &thrust_max, RangeLimit{},
                  "[N] NMPC thrust input bounds [min, max]; min below every vehicle's weight m g, "
                  "max ≥ 1.2 m g");
    a->Visit("controller.bounds.attitude_ref", &max_attitude_ref, Positive().Below(1.2, "rad"),
             "[rad] |roll_ref|, |pitch_ref| bound");
    a->Visit("controller.bounds.speed", &max_speed, Positive(),
             "[m/s] velocity bound per axis, soft (exact penalty: never makes a QP infeasible)");
    a->Visit("leader.start_time", &trajectory_start, Positive(),
             "[s] start of the leader's first leg (take-off and engagement happen before)");
    a->Visit("phases.takeoff_time", &takeoff_time, NonNegative(), "[s] motors start");
    a->Visit("phases.takeoff_height", &takeoff_height, Positive().AtLeast(0.3, "m"),
             "[m] CoM height above the ground at the switch to the NMPC");
    a->Visit("phases.climb_speed", &climb_speed, Positive(), "[m/s] PID climb");
    a->Visit("phases.hover_before_switch", &hover_before_switch, NonNegative(),
             "[s] PID hover at the take-off height before the switch");
    a->Visit("phases.blend_time", &blend_time, NonNegative(),
             "[s] linear blend PID → NMPC (and NMPC → PID)");
    a->Visit("phases.landing_time", &landing_time, Positive(),
             "[s] start of the PID descent; between `leader.start_time` and `duration`");
    a->Visit("phases.descent_speed", &descent_speed, Positive(), "[m/s] PID descent");
    a->Nested("safety", &safety);
  }
};

}  // namespace fnmpc::formation

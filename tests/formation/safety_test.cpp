// SPDX-License-Identifier: BSD-3-Clause
// Safety behaviour of the VehicleController: soft state bounds, the recovery ladder and the
// failsafe controller, neighbour loss, and no allocation in flight (malloc level).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "tests/formation/controller_test_support.hpp"
#include "tests/support/malloc_counter.hpp"

namespace fnmpc::formation {
namespace {

using testing::BaseConfig;
using testing::Fly;
using testing::kGround;
using testing::kTs;
using testing::Plant;

TEST(MallocCounterTest, SeesDirectEigenAndNewAllocations) {
  // The counter must be able to fail: a direct malloc and a dynamic Eigen matrix are seen,
  void* volatile p = nullptr;
  EXPECT_EQ(::fnmpc::testing::CountMallocs([&] { p = std::malloc(64); }), 1);
  std::free(p);
  EXPECT_GE(::fnmpc::testing::CountMallocs([] {
              Eigen::MatrixXd m(40, 40);
              m.setOnes();
              volatile double s = m.sum();
              (void)s;
            }),
            1);
  // and so is operator new (std::vector), through the replaced operator new
  EXPECT_GE(::fnmpc::testing::CountMallocs([] {
              std::vector<int> v(100, 1);
              volatile int s = v[50];
              (void)s;
            }),
            1);
  EXPECT_EQ(::fnmpc::testing::CountMallocs([] {}), 0);
}

TEST(SafetyTest, LeaderOverSpeedComesBackWithoutFallback) {
  // Given a leader hovering under the NMPC
  VehicleController c(BaseConfig(true));
  Plant plant;
  double t = 0.0;
  for (; t <= 6.0; t += kTs) plant.Step(c.ControlWithEstimates(t, plant.Estimate(t), {}));
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  // When it is pushed to 2.05 m/s, beyond its 2 m/s speed bound
  plant.x[3] = 2.05;
  double back = kNaN;
  for (double s = 0.0; s <= 2.0; s += kTs, t += kTs) {
    const ControlOutput o = c.ControlWithEstimates(t, plant.Estimate(t), {});
    // Then every QP is feasible (soft state bounds): no fallback
    EXPECT_FALSE(o.fallback) << "t = " << t;
    EXPECT_EQ(o.status, rti::RtiStatus::kSuccess);
    plant.Step(o);
    if (std::isnan(back) && plant.x.segment<3>(3).cwiseAbs().maxCoeff() <= 2.0) back = s + kTs;
  }
  // and it is back within its bound in at most 1 s
  ASSERT_TRUE(std::isfinite(back));
  EXPECT_LE(back, 1.0);
  std::printf("[   INFO   ] back within the speed bound after %.2f s\n", back);
  EXPECT_EQ(c.fallbacks(), 0);
}

TEST(SafetyTest, LeaderKeepsMinimumAltitudeWithWaypointBelowGround) {
  // Given a leader whose trajectory goes 2 m down from its 1 m hover point
  ControllerConfig cfg = BaseConfig(true);
  cfg.trajectory = WaypointTrajectory::Uniform({Vec3::Zero(), Vec3(0, 0, -2.0)}, 3.0, 5.0);
  cfg.trajectory_start = 5.0;
  VehicleController c(cfg);
  Plant plant;
  double zmin = kInf;
  for (double t = 0.0; t <= 14.0; t += kTs) {
    const ControlOutput o = c.ControlWithEstimates(t, plant.Estimate(t), {});
    plant.Step(o);
    if (c.phase() == FlightPhase::kNmpc) zmin = std::min(zmin, plant.x[2]);
    EXPECT_FALSE(o.fallback);
  }
  // Then the soft altitude bound keeps it above the ground (min_altitude 0.3 m, a few cm
  // of slack allowed by the exact penalty's linearisation)
  EXPECT_GT(zmin, cfg.safety.min_altitude - 0.05);
  EXPECT_LT(zmin, 0.45);  // it did go down as far as allowed
}

TEST(SafetyTest, UnusableEstimateHandsOverToFailsafeThatLands) {
  // Given a leader hovering under the NMPC
  ControllerConfig cfg = BaseConfig(true);
  VehicleController c(cfg);
  Plant plant;
  double t = 0.0;
  for (; t <= 6.0; t += kTs) plant.Step(c.ControlWithEstimates(t, plant.Estimate(t), {}));
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  // When its horizontal estimate is lost (velocity NaN) for longer than the timeout
  bool failsafe_logged = false;
  double t_fs = kNaN;
  for (double s = 0.0; s < 1.0; s += kTs, t += kTs) {
    estimation::VehicleEstimate e = plant.Estimate(t);
    e.velocity.x() = kNaN;
    const ControlOutput o = c.ControlWithEstimates(t, e, {});
    if (o.recovery == RecoveryAction::kFailsafe) {
      failsafe_logged = true;
      t_fs = s;
      EXPECT_EQ(o.recovery_reason, RecoveryReason::kEstimateUnusable);
    }
    EXPECT_TRUE(std::isfinite(o.thrust));
    plant.Step(o);
  }
  // Then the ladder hands over after estimate_timeout, says why, and the failsafe holds level
  ASSERT_TRUE(failsafe_logged);
  EXPECT_NEAR(t_fs, cfg.safety.recovery.estimate_timeout, kTs + 1e-9);
  EXPECT_TRUE(c.failsafe());
  EXPECT_EQ(c.failsafe_reason(), RecoveryReason::kEstimateUnusable);
  // and lands: descends at the failsafe rate and stops the motors on the ground
  double vz_min = 0.0;
  for (double s = 0.0; s < 10.0 && c.phase() != FlightPhase::kLanded; s += kTs, t += kTs) {
    estimation::VehicleEstimate e = plant.Estimate(t);
    e.velocity.x() = kNaN;
    const ControlOutput o = c.ControlWithEstimates(t, e, {});
    EXPECT_EQ(o.roll, 0.0);
    EXPECT_EQ(o.pitch, 0.0);
    plant.Step(o);
    vz_min = std::min(vz_min, plant.x[5]);
  }
  EXPECT_EQ(c.phase(), FlightPhase::kLanded);
  EXPECT_NEAR(plant.x[2], kGround, 0.02);
  EXPECT_GT(vz_min, -(cfg.safety.recovery.failsafe_descent_speed + 0.15));
}

TEST(SafetyTest, CommandedFailsafeLandsFromAnyHeight) {
  ControllerConfig cfg = BaseConfig(true);
  cfg.takeoff_height = 2.0;
  VehicleController c(cfg);
  Plant plant;
  double t = 0.0;
  for (; t <= 9.0; t += kTs) plant.Step(c.ControlWithEstimates(t, plant.Estimate(t), {}));
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  c.TriggerFailsafe(t);
  EXPECT_EQ(c.failsafe_reason(), RecoveryReason::kCommanded);
  for (double s = 0.0; s < 15.0 && c.phase() != FlightPhase::kLanded; s += kTs, t += kTs)
    plant.Step(c.ControlWithEstimates(t, plant.Estimate(t), {}));
  EXPECT_EQ(c.phase(), FlightPhase::kLanded);
  EXPECT_NEAR(plant.x[2], kGround, 0.02);
}

TEST(SafetyTest, FailsafeDescentFromJustAboveTheGroundKeepsTheMotorsOnUntilContact) {
  // Given a leader whose failsafe holds 2 cm above its resting height, within the
  // touchdown margin (3 cm; fault campaign run 55: a follower that had bounced off the
  // ground hovered there when its failsafe began),
  // (a take-off to 2 cm, the failsafe triggered in its hover before the NMPC takes over)
  ControllerConfig cfg = BaseConfig(true);
  cfg.takeoff_height = kGround + 0.02;
  cfg.hover_before_switch = 10.0;
  cfg.safety.recovery.failsafe_hold_time = 2.0;
  VehicleController c(cfg);
  Plant plant;
  double t = 0.0;
  for (; t < 4.0; t += kTs) plant.Step(c.ControlWithEstimates(t, plant.Estimate(t), {}));
  ASSERT_EQ(c.phase(), FlightPhase::kTakeoff);
  c.TriggerFailsafe(t);
  for (double s = 0.0; s < cfg.safety.recovery.failsafe_hold_time; s += kTs, t += kTs)
    plant.Step(c.ControlWithEstimates(t, plant.Estimate(t), {}));
  ASSERT_NEAR(plant.x[2], kGround + 0.02, 0.005);
  // When it descends
  double motors_off_height = kNaN;
  for (double s = 0.0; s < 5.0 && c.phase() != FlightPhase::kLanded; s += kTs, t += kTs) {
    const ControlOutput o = c.ControlWithEstimates(t, plant.Estimate(t), {});
    if (o.phase == FlightPhase::kLanded) motors_off_height = plant.x[2];
    plant.Step(o);
  }
  // Then the motors stop only on the ground (the contact held for 0.3 s; before, they stopped
  // at once, 2 cm up, and it fell: 0.63 m/s against the 0.6 m/s touchdown limit)
  ASSERT_EQ(c.phase(), FlightPhase::kLanded);
  for (int k = 0; k < 10; ++k, t += kTs)  // what the motors' stop leaves falls
    plant.Step(c.ControlWithEstimates(t, plant.Estimate(t), {}));
  EXPECT_NEAR(motors_off_height, kGround, 1e-9);
  ASSERT_TRUE(std::isfinite(plant.impact_vz));
  EXPECT_GT(plant.impact_vz, -(cfg.safety.recovery.failsafe_descent_speed + 0.1));
  std::printf("[   INFO   ] touchdown from 2 cm: %.3f m/s\n", plant.impact_vz);
}

/// The follower of the neighbour-loss tests below: in formation with its leader (vehicle 0)
/// and vehicle 2, all hovering at about 1.1 m, where they start.
ControllerConfig FollowerOfTwo() {
  ControllerConfig cfg = BaseConfig(false);
  cfg.neighbours = {{0, Vec3(1.0, -1.0, 0.0)}, {2, Vec3(-1.0, 0.0, 0.0)}};
  return cfg;
}
const Vec3 kLeaderStart(1.3, -0.8, 1.1);
const Vec3 kVehicle2Start(-0.7, 0.2, 1.1);

/// What that follower senses at t: its own estimate (height above the ground) and, in *nb,
/// its leader at p0 moving at v0 and vehicle 2 at p2 moving at v2 (relative positions from
/// the plant's truth).
estimation::VehicleEstimate SenseTwo(const Plant& plant, double t, const Vec3& p0, const Vec3& v0,
                                     const Vec3& p2, const Vec3& v2,
                                     std::vector<estimation::NeighbourStateVec>* nb) {
  estimation::VehicleEstimate e = plant.Estimate(t);
  e.position.z() -= kGround;
  nb->resize(2);
  for (std::size_t k = 0; k < 2; ++k) {
    (*nb)[k].setZero();
    (*nb)[k].head<3>() = (k == 0 ? p0 : p2) - plant.x.head<3>();
    (*nb)[k].segment<3>(3) = k == 0 ? v0 : v2;
  }
  return e;
}

/// A follower hovering in formation with its leader (vehicle 0) and vehicle 2; at 8 s
/// vehicle 2 comes down (a killed vehicle landed by its autopilot) 0.1 m beside the point
/// under the follower; the follower lands at 12 s. Returns the smallest CoM distance to
/// vehicle 2 during the landing, its horizontal distance at the end, and the outputs.
struct LandingResult {
  double min_distance = kInf, final_horizontal = kNaN;
  std::vector<ControlOutput> out;
};
// `tilt_bias` [rad] is added to every pitch command and subtracted from every roll command on
// their way to the plant (an autopilot's attitude bias, tilting it towards the downed vehicle;
// the landing PID's position loop holds against it with an offset).
LandingResult LandBesideDownedVehicle(double collision_radius, double tilt_bias = 0.0) {
  ControllerConfig cfg = FollowerOfTwo();
  cfg.safety.collision_radius = collision_radius;
  cfg.landing_time = 12.0;
  VehicleController c(cfg);
  Plant plant;
  Vec3 p2 = kVehicle2Start;
  std::vector<estimation::NeighbourStateVec> nb;
  LandingResult r;
  for (double t = 0.0; t <= 22.0 && c.phase() != FlightPhase::kLanded; t += kTs) {
    if (t >= 8.0 && p2.z() > kGround) {
      p2 = Vec3(plant.x[0] + 0.08, plant.x[1] + 0.06, kGround);
    }
    const estimation::VehicleEstimate e =
        SenseTwo(plant, t, kLeaderStart, Vec3::Zero(), p2, Vec3::Zero(), &nb);
    r.out.push_back(c.ControlWithEstimates(t, e, nb));
    ControlOutput applied = r.out.back();
    applied.roll -= tilt_bias;
    applied.pitch += tilt_bias;
    plant.Step(applied);
    if (c.phase() == FlightPhase::kLanding || c.phase() == FlightPhase::kLanded)
      r.min_distance = std::min(r.min_distance, (plant.x.head<3>() - p2).norm());
  }
  EXPECT_EQ(c.phase(), FlightPhase::kLanded) << "radius " << collision_radius;
  r.final_horizontal = (plant.x.head<2>() - p2.head<2>()).norm();
  return r;
}

TEST(SafetyTest, LandingMovesItsSiteClearOfAVehicleBelow) {
  // Without collision avoidance (r_min 0) the follower lands on the downed vehicle
  const LandingResult off = LandBesideDownedVehicle(0.0);
  EXPECT_LT(off.final_horizontal, 0.15);
  // With it the landing moves its site to r_min + 0.1 m from the vehicle below, says so once
  // with the reason, descends only once clear, and lands there
  const double r = 0.45;
  const LandingResult on = LandBesideDownedVehicle(r);
  std::printf(
      "[   INFO   ] landing beside a downed vehicle: min distance %.3f m without, %.3f m "
      "with r_min %.2f m (final horizontal %.3f m)\n",
      off.min_distance, on.min_distance, r, on.final_horizontal);
  int shifts = 0;
  for (const ControlOutput& o : on.out) {
    if (o.recovery != RecoveryAction::kShiftLandingSite) continue;
    ++shifts;
    EXPECT_EQ(o.recovery_reason, RecoveryReason::kVehicleBelow);
    EXPECT_EQ(o.phase, FlightPhase::kLanding);
  }
  EXPECT_EQ(shifts, 1);
  EXPECT_GT(on.final_horizontal, r);
  // near the moved site (r_min + 0.1 m; the PID's position loop overshoots a step by about
  // 0.1 m: its integral's zero)
  EXPECT_LT(on.final_horizontal, r + 0.1 + 0.15);
  EXPECT_GT(on.min_distance, r - 0.02);
}

TEST(SafetyTest, LandingHeldOffItsSiteMovesTheSiteOnInsteadOfWaiting) {
  // Given a follower whose autopilot tilts 0.05 rad (roll and pitch) towards the downed
  // vehicle more than commanded: its landing PID holds it off the moved site towards it
  const double r = 0.45;
  const LandingResult on = LandBesideDownedVehicle(r, 0.05);
  int shifts = 0;
  for (const ControlOutput& o : on.out) shifts += o.recovery == RecoveryAction::kShiftLandingSite;
  std::printf(
      "[   INFO   ] held off its site: %d site moves, final horizontal %.3f m, min distance "
      "%.3f m, landed at %.2f s\n",
      shifts, on.final_horizontal, on.min_distance, on.out.back().time);
  // Then the site moves on while the descent waits (more than the one move), the vehicle
  // lands in the run (LandBesideDownedVehicle checks) and clear of the vehicle below
  EXPECT_GE(shifts, 2);
  EXPECT_GT(on.final_horizontal, r);
  EXPECT_GT(on.min_distance, r - 0.02);
}

TEST(SafetyTest, LandingStartsFromTheMeanThrustNotFromAnOutlyingLastCommand) {
  // Given a leader hovering under the NMPC, landing at 8 s
  ControllerConfig cfg = BaseConfig(true);
  cfg.landing_time = 8.0;
  VehicleController c(cfg);
  Plant plant;
  const int landing_step = 160;  // t = 8 s
  double last_nmpc = kNaN, first_landing = kNaN;
  for (int k = 0; k <= landing_step + 2; ++k) {
    const double t = k * kTs;
    estimation::VehicleEstimate e = plant.Estimate(t);
    // When its last NMPC step sees it 0.3 m too high (one glitching sample; at the altitude
    // bound the NMPC's thrust swings as far from step to step)
    if (k == landing_step - 1) e.position.z() += 0.3;
    const ControlOutput o = c.ControlWithEstimates(t, e, {});
    if (o.phase == FlightPhase::kNmpc) last_nmpc = o.thrust;
    if (o.phase == FlightPhase::kLanding && std::isnan(first_landing)) first_landing = o.thrust;
    plant.Step(o);
  }
  const double hover = cfg.params.mass * kGravity;
  std::printf("[   INFO   ] hover %.2f N, last NMPC command %.2f N, first landing command %.2f N\n",
              hover, last_nmpc, first_landing);
  // (the NMPC answers the glitch far below hover)
  ASSERT_LT(last_nmpc, hover - 1.0);
  // Then the landing PID starts from the recent mean command: about hover, the glitch's
  // command weighing 1 - exp(-kTs / blend_time) in it, not from that command alone
  const double a = 1.0 - std::exp(-kTs / cfg.blend_time);
  EXPECT_NEAR(first_landing, hover + a * (last_nmpc - hover), 0.15);
}

TEST(SafetyTest, FollowerDoesNotFollowAFallingNeighbourIntoTheGround) {
  // Given a follower in formation with its leader (vehicle 0, desired at the same height) and
  // vehicle 2, all at about 1.1 m, its height known (the altitude bound applies)
  const ControllerConfig cfg = FollowerOfTwo();
  VehicleController c(cfg);
  Plant plant;
  Vec3 p0 = kLeaderStart, v0 = Vec3::Zero();
  std::vector<estimation::NeighbourStateVec> nb;
  double zmin = kInf, t_impact = kNaN;
  for (double t = 0.0; t <= 16.0; t += kTs) {
    // When the leader's motors stop at 8 s (fault campaign run 55): it falls freely onto the
    // ground; its estimate, as the follower's filter gave it in that run, goes on falling at
    // the impact speed (the filter gates the measurements of the stopped vehicle) until it
    // is dropped for want of accepted measurements, neighbour_timeout later
    if (t >= 8.0) {
      v0.z() -= std::isnan(t_impact) ? kGravity * kTs : 0.0;
      p0.z() += v0.z() * kTs;
      if (std::isnan(t_impact) && p0.z() <= kGround) t_impact = t;
    }
    const bool lost = t >= t_impact + cfg.safety.neighbour_timeout;
    const estimation::VehicleEstimate e =
        SenseTwo(plant, t, p0, v0, kVehicle2Start, Vec3::Zero(), &nb);
    if (lost) nb[0].setConstant(kNaN);
    // (ControlWithEstimates has no motion capture: the height is the estimate's)
    const ControlOutput o = c.ControlWithEstimates(t, e, nb);
    EXPECT_FALSE(o.fallback) << "t = " << t;
    plant.Step(o);
    if (t >= 8.0) zmin = std::min(zmin, plant.x[2]);
  }
  ASSERT_TRUE(std::isfinite(t_impact));
  std::printf("[   INFO   ] follower's lowest CoM after its leader fell: %.3f m\n", zmin);
  // Then it never touches the ground: the leader is held on the ground in the prediction
  // (not below it), so the altitude bound (min_altitude 0.3 m, a few cm of slack) holds
  EXPECT_TRUE(std::isnan(plant.impact_vz)) << "struck the ground at " << plant.impact_vz;
  EXPECT_GT(zmin, cfg.safety.min_altitude - 0.05);
  // and the lost leader left the cost
  EXPECT_FALSE(c.neighbour_active(0));
  EXPECT_TRUE(c.neighbour_active(1));
}

/// A follower in formation with its leader (vehicle 0) and vehicle 2, all at about 1.1 m;
/// from t_fail vehicle 2 descends at 0.7 m/s onto the ground (a killed controller's
/// autopilot landing it). Returns the follower's largest sink below its height at t_fail [m]
/// and sets *departed_at to when vehicle 2 left its cost for leaving the formation (NaN:
/// never) and *dropped_at to when it left the cost for any reason.
double SinkBehindDescendingNeighbour(const ControllerConfig& cfg, double t_fail,
                                     double* departed_at, double* dropped_at) {
  VehicleController c(cfg);
  Plant plant;
  Vec3 p2 = kVehicle2Start;
  std::vector<estimation::NeighbourStateVec> nb;
  double z_fail = kNaN, sink = 0.0;
  *departed_at = *dropped_at = kNaN;
  for (double t = 0.0; t <= t_fail + 6.0; t += kTs) {
    double v2 = 0.0;
    if (t >= t_fail && p2.z() > kGround) {
      v2 = -0.7;
      p2.z() = std::max(kGround, p2.z() + v2 * kTs);
    }
    const estimation::VehicleEstimate e =
        SenseTwo(plant, t, kLeaderStart, Vec3::Zero(), p2, Vec3(0.0, 0.0, v2), &nb);
    const ControlOutput o = c.ControlWithEstimates(t, e, nb);
    EXPECT_FALSE(o.fallback) << "t = " << t;
    plant.Step(o);
    if (t >= t_fail) {
      if (std::isnan(z_fail)) z_fail = plant.x[2];
      sink = std::max(sink, z_fail - plant.x[2]);
      if (c.neighbour_departed(1) && std::isnan(*departed_at)) *departed_at = t;
      if (!c.neighbour_active(1) && std::isnan(*dropped_at)) *dropped_at = t;
    }
  }
  // The leader stays in the cost, and the follower flies on with it (no landing).
  EXPECT_TRUE(c.neighbour_active(0));
  EXPECT_EQ(c.phase(), FlightPhase::kNmpc);
  EXPECT_EQ(c.tie_loss(), RecoveryReason::kNone);
  return sink;
}

/// The follower of FollowerOfTwo with the neighbours' depths known (leader 0, vehicle 2 a
/// row-mate at 1); from 8 s vehicle 2 drifts sideways at 0.6 m/s for 2 s (a killed
/// controller's autopilot holding its last tilt) and stops. Returns the follower's largest
/// horizontal excursion from its place at 8 s [m].
double ExcursionBehindDriftingNeighbour(double tie_disagreement) {
  ControllerConfig cfg = FollowerOfTwo();
  cfg.leader_vehicle = 0;
  cfg.neighbours[0].depth = 0;
  cfg.neighbours[1].depth = 1;
  cfg.tie_disagreement = tie_disagreement;
  VehicleController c(cfg);
  Plant plant;
  Vec3 p2 = kVehicle2Start;
  std::vector<estimation::NeighbourStateVec> nb;
  Vec3 place = Vec3::Constant(kNaN);
  double excursion = 0.0;
  for (double t = 0.0; t <= 14.0; t += kTs) {
    const Vec3 v2 = t >= 8.0 && t < 10.0 ? Vec3(0.0, 0.6, 0.0) : Vec3::Zero();
    p2 += kTs * v2;
    const estimation::VehicleEstimate e =
        SenseTwo(plant, t, kLeaderStart, Vec3::Zero(), p2, v2, &nb);
    const ControlOutput o = c.ControlWithEstimates(t, e, nb);
    EXPECT_FALSE(o.fallback) << "t = " << t;
    plant.Step(o);
    if (t >= 8.0) {
      if (!place.allFinite()) place = plant.x.head<3>();
      excursion = std::max(excursion, (plant.x.head<2>() - place.head<2>()).norm());
    }
  }
  EXPECT_TRUE(c.neighbour_active(1));  // sideways: the departure rule does not drop it
  return excursion;
}

TEST(SafetyTest, RowMateDriftingSidewaysPullsTheFollowerLittle) {
  // Given the follower with equal tie weights, when its row-mate drifts 1.2 m sideways
  const double off = ExcursionBehindDriftingNeighbour(0.0);
  const double on = ExcursionBehindDriftingNeighbour(0.25);
  std::printf(
      "[   INFO   ] excursion behind a drifting row-mate: %.3f m equal weights, %.3f m "
      "with tie_disagreement 0.25 m\n",
      off, on);
  // Then with equal weights it follows about half of it; discounting the disagreeing tie
  // leaves it near its place relative to the leader: what it still follows is the start of
  // the drift, while the disagreement is below the scale (under a third of the excursion)
  EXPECT_GT(off, 0.4);
  EXPECT_LT(on, off / 3.0);
}

TEST(SafetyTest, NeighbourDescendingOutOfTheFormationLeavesTheCostBeforeItLands) {
  // Given a follower with its leader and vehicle 2 (kill-follower scenario: follower2's
  // autopilot lands it after its controller died), the leader known as vehicle 0
  ControllerConfig cfg = FollowerOfTwo();
  cfg.leader_vehicle = 0;
  const double t_fail = 8.0;
  // When vehicle 2 descends at 0.7 m/s from t_fail
  double departed = kNaN, dropped = kNaN;
  const double sink = SinkBehindDescendingNeighbour(cfg, t_fail, &departed, &dropped);
  // and the same without the departure rule (it leaves only once seen on the ground)
  ControllerConfig off = cfg;
  off.safety.neighbour_departure_height = 0.0;
  double departed_off = kNaN, dropped_off = kNaN;
  const double sink_off = SinkBehindDescendingNeighbour(off, t_fail, &departed_off, &dropped_off);
  std::printf(
      "[   INFO   ] departure at %.2f s, sink %.3f m; without: dropped at %.2f s, sink %.3f m\n",
      departed - t_fail, sink, dropped_off - t_fail, sink_off);
  // Then it leaves the cost once 0.5 m below its place relative to the leader (0.71 s) and
  // that held for 0.3 s, long before it is on the ground
  ASSERT_TRUE(std::isfinite(departed));
  EXPECT_NEAR(departed - t_fail, 0.5 / 0.7 + cfg.safety.neighbour_departure_time, 2 * kTs);
  EXPECT_NEAR(dropped, departed, 1e-9);
  EXPECT_TRUE(std::isnan(departed_off));
  EXPECT_GT(dropped_off - t_fail, 1.0 / 0.7 + cfg.safety.neighbour_timeout - 0.3);
  // and the follower, averaging its two neighbours, sinks about half their vertical
  // discrepancy at the departure (0.5 m plus 0.7 m/s over the departure time and a step),
  // no longer half the whole descent.
  const double h = cfg.safety.neighbour_departure_height;
  EXPECT_LT(sink, 0.5 * (h + 0.7 * (cfg.safety.neighbour_departure_time + kTs)) + 0.03);
  EXPECT_LT(sink, sink_off - 0.1);
}

TEST(SafetyTest, FollowerFailsafeDescentWithoutMotionCaptureKeepsItsRate) {
  // Given a follower hovering under the NMPC with motion capture at 60 Hz (its height loops
  // close on the raw motion-capture height while it is fresh)
  ControllerConfig cfg = BaseConfig(false);
  VehicleController c(cfg);
  Plant plant;
  const Vec3 p0(1.3, -0.8, 1.1);
  double t = 0.0, next_mocap = 0.0;
  bool mocap = true;
  auto step = [&] {
    for (; next_mocap <= t; next_mocap += 1.0 / 60.0) {
      if (mocap) c.Process(plant.Mocap(cfg.vehicle, next_mocap));
    }
    estimation::VehicleEstimate e = plant.Estimate(t);
    e.position.z() -= kGround;
    std::vector<estimation::NeighbourStateVec> nb(1, estimation::NeighbourStateVec::Zero());
    nb[0].head<3>() = p0 - plant.x.head<3>();
    const ControlOutput o = c.ControlWithEstimates(t, e, nb);
    plant.Step(o);
    t += kTs;
    return o;
  };
  while (t <= 8.0) step();
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  // When its failsafe descends and the motion capture is lost half-way down (fault campaign
  // run 8: a mocap dropout in the failsafe's descent)
  c.TriggerFailsafe(t);
  const double t_fs = t;
  const double fs = cfg.safety.recovery.failsafe_descent_speed;
  while (c.phase() != FlightPhase::kLanded && t < t_fs + 20.0) {
    if (t >= t_fs + cfg.safety.recovery.failsafe_hold_time + 0.5 * plant.x[2] / fs) mocap = false;
    const ControlOutput o = step();
    EXPECT_TRUE(std::isfinite(o.thrust));
  }
  // Then, on its estimated height once the last motion-capture height is kMaxMocapGap old,
  // it touches down at about the failsafe rate (with that height held: at -0.88 m/s, the
  // reference running away below a frozen height) and lands
  ASSERT_FALSE(mocap);
  EXPECT_EQ(c.phase(), FlightPhase::kLanded);
  EXPECT_GT(plant.impact_vz, -(fs + 0.15));
  EXPECT_NEAR(plant.x[2], kGround, 0.02);
}

TEST(SafetyTest, FailsafeHoldIgnoresMotionCaptureOutliers) {
  // Given a leader hovering under the NMPC with motion capture at 60 Hz
  ControllerConfig cfg = BaseConfig(true);
  VehicleController c(cfg);
  Plant plant;
  double t = 0.0;
  double next_mocap = 0.0;
  int sample = 0;
  auto feed_mocap = [&](double until, bool outliers) {
    for (; next_mocap <= until; next_mocap += 1.0 / 60.0, ++sample) {
      Measurement m = plant.Mocap(cfg.vehicle, next_mocap);
      // every fifth sample 0.8 m off (the fault campaign's outlier sizes reach 1 m)
      if (outliers && sample % 5 == 0) m.position.z() += 0.8;
      c.Process(m);
    }
  };
  for (; t <= 6.0; t += kTs) {
    feed_mocap(t, false);
    plant.Step(c.ControlWithEstimates(t, plant.Estimate(t), {}));
  }
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  // When the failsafe holds the altitude from the raw motion-capture height and rate while
  // the motion capture delivers outliers
  c.TriggerFailsafe(t);
  const double z0 = plant.x[2];
  const double hover = cfg.params.mass * kGravity;
  double thrust_dev = 0.0, z_dev = 0.0;
  for (double s = 0.0; s < cfg.safety.recovery.failsafe_hold_time; s += kTs, t += kTs) {
    feed_mocap(t, true);
    const ControlOutput o = c.ControlWithEstimates(t, plant.Estimate(t), {});
    thrust_dev = std::max(thrust_dev, std::abs(o.thrust - hover));
    plant.Step(o);
    z_dev = std::max(z_dev, std::abs(plant.x[2] - z0));
  }
  // Then the thrust stays near hover (a 0.8 m jump would ask kp_z * 0.8 * m = 7.4 N, and the
  // raw rate's jump far more) and the height holds
  EXPECT_LT(thrust_dev, 1.0);
  EXPECT_LT(z_dev, 0.05);
}

/// A follower with two neighbours hovering still; neighbour 1 disappears at t_loss and
/// comes back at t_back. Returns the outputs.
std::vector<ControlOutput> FlyFollowerWithLoss(VehicleController* c, Plant* plant, double t_loss,
                                               double t_back, double until) {
  const Vec3 p0(1.3, -0.8, 1.1), p1(-1.0, -1.2, 1.0);
  std::vector<estimation::NeighbourStateVec> nb(2);
  std::vector<ControlOutput> out;
  for (double t = 0.0; t <= until; t += kTs) {
    estimation::VehicleEstimate e = plant->Estimate(t);
    e.position.z() -= kGround;
    nb[0].setZero();
    nb[0].head<3>() = p0 - plant->x.head<3>();
    nb[1].setZero();
    nb[1].head<3>() = p1 - plant->x.head<3>();
    if (t >= t_loss && t < t_back) nb[1].setConstant(kNaN);
    out.push_back(c->ControlWithEstimates(t, e, nb));
    plant->Step(out.back());
  }
  return out;
}

TEST(SafetyTest, LostNeighbourLeavesTheCostAndReturnsWithHysteresis) {
  // Given a follower whose two neighbours' desired offsets are inconsistent by 0.6 m in y
  ControllerConfig cfg = BaseConfig(false);
  cfg.neighbours = {{0, Vec3(1.0, -1.0, 0.0)}, {2, Vec3(-1.3, -1.4 + 0.6, 0.0)}};
  VehicleController c(cfg);
  Plant plant;
  // When neighbour 1 is lost at 10 s and seen again from 16 s
  const auto out = FlyFollowerWithLoss(&c, &plant, 10.0, 16.0, 24.0);
  auto at = [&out](double t) { return out[static_cast<std::size_t>(std::lround(t / kTs))]; };
  // Then it flies with both, then only neighbour 0 after the timeout, then both again
  // after the reacquisition time
  EXPECT_EQ(at(9.9).active_neighbours, 2);
  EXPECT_EQ(at(10.0 + cfg.safety.neighbour_timeout + 0.1).active_neighbours, 1);
  EXPECT_EQ(at(16.0 + cfg.safety.neighbour_reacquire_time + 0.15).active_neighbours, 2);
  // and without neighbour 1 it holds neighbour 0's offset alone (the compromise is gone)
  const Vec3 p0(1.3, -0.8, 1.1);
  std::vector<ControlOutput> tail;
  Plant check;
  VehicleController c2(cfg);
  FlyFollowerWithLoss(&c2, &check, 10.0, 1e9, 15.5);
  EXPECT_LT(((p0 - check.x.head<3>()) - Vec3(1.0, -1.0, 0.0)).norm(), 0.03);
  // and nothing fell back, nothing handed over to the failsafe
  EXPECT_EQ(c.fallbacks(), 0);
  EXPECT_FALSE(c.failsafe());
}

// The first time [s] `out` is in `phase` (NaN: never).
double FirstIn(const std::vector<ControlOutput>& out, FlightPhase phase) {
  for (const ControlOutput& o : out) {
    if (o.phase == phase) return o.time;
  }
  return kNaN;
}

TEST(SafetyTest, NeighbourNeverSeenDoesNotHoldTheTakeoff) {
  // Given a follower with two neighbours, one of which it never senses (out of range),
  ControllerConfig cfg = BaseConfig(false);
  cfg.neighbours = {{0, Vec3(1.0, -1.0, 0.0)}, {2, Vec3(-1.3, -1.4, 0.0)}};
  VehicleController c(cfg);
  Plant plant;
  // When it takes off and flies for 15 s (neighbour 1 "lost" from t = 0 on),
  const auto out = FlyFollowerWithLoss(&c, &plant, 0.0, 1e9, 15.0);
  // Then it hands over to the NMPC neighbour_timeout after it would have with both (it
  // hovered in its take-off for the whole flight before),
  const double takeoff = FirstIn(out, FlightPhase::kTakeoff);
  const double nmpc = FirstIn(out, FlightPhase::kNmpc);
  ASSERT_TRUE(std::isfinite(nmpc));
  EXPECT_GE(nmpc - takeoff, cfg.hover_before_switch + cfg.safety.neighbour_timeout);
  EXPECT_LT(nmpc - takeoff, 8.0);
  // with the neighbour it sees in its cost and holds that neighbour's offset alone,
  EXPECT_EQ(out.back().active_neighbours, 1);
  const Vec3 p0(1.3, -0.8, 1.1);
  EXPECT_LT(((p0 - plant.x.head<3>()) - Vec3(1.0, -1.0, 0.0)).norm(), 0.03);
  EXPECT_EQ(c.fallbacks(), 0);
  EXPECT_FALSE(c.failsafe());
}

TEST(SafetyTest, NoNeighbourSeenLandsFromTheTakeoff) {
  // Given a follower that never senses its only neighbour,
  ControllerConfig cfg = BaseConfig(false);
  VehicleController c(cfg);
  Plant plant;
  std::vector<ControlOutput> out;
  const std::vector<estimation::NeighbourStateVec> none(
      1, estimation::NeighbourStateVec::Constant(kNaN));
  // When it takes off and 20 s pass,
  for (double t = 0.0; t <= 20.0; t += kTs) {
    estimation::VehicleEstimate e = plant.Estimate(t);
    e.position.z() -= kGround;
    out.push_back(c.ControlWithEstimates(t, e, none));
    plant.Step(out.back());
  }
  // Then it never starts the NMPC: at height for hover_before_switch + neighbour_timeout it
  // lands where it is, saying why, and touches down gently with its motors off.
  EXPECT_TRUE(std::isnan(FirstIn(out, FlightPhase::kNmpc)));
  const auto land = std::find_if(out.begin(), out.end(), [](const ControlOutput& o) {
    return o.recovery == RecoveryAction::kLand;
  });
  ASSERT_NE(land, out.end());
  EXPECT_EQ(land->recovery_reason, RecoveryReason::kNoNeighbourSeen);
  EXPECT_GE(land->time - FirstIn(out, FlightPhase::kTakeoff),
            cfg.hover_before_switch + cfg.safety.neighbour_timeout);
  EXPECT_EQ(c.phase(), FlightPhase::kLanded);
  EXPECT_GT(plant.impact_vz, -0.6);
  EXPECT_EQ(out.back().thrust, 0.0);
}

TEST(SafetyTest, LandingTimeEndsATakeoffThatHasNotCompleted) {
  // Given a leader whose landing time comes while it still climbs,
  ControllerConfig cfg = BaseConfig(true);
  cfg.landing_time = 1.5;
  VehicleController c(cfg);
  Plant plant;
  // When 10 s pass,
  const auto out = Fly(&c, &plant, 10.0);
  // Then it lands from its take-off at the landing time (it climbed on before) and is down.
  EXPECT_TRUE(std::isnan(FirstIn(out, FlightPhase::kNmpc)));
  EXPECT_NEAR(FirstIn(out, FlightPhase::kLanding), cfg.landing_time, kTs / 2);
  EXPECT_EQ(c.phase(), FlightPhase::kLanded);
  EXPECT_GT(plant.impact_vz, -0.6);
}

TEST(SafetyTest, NoAllocationFromTakeoffToLanding) {
  // Given a leader and a follower built (all allocation happens here)
  ControllerConfig lc = BaseConfig(true);
  lc.landing_time = 9.0;
  ControllerConfig fc = BaseConfig(false);
  fc.landing_time = 14.0;
  VehicleController leader(lc), follower(fc);
  Plant pl, pf;
  const Vec3 p0(1.3, -0.8, 1.1);
  std::vector<estimation::NeighbourStateVec> nb(1);
  estimation::NeighbourStateVec lost = estimation::NeighbourStateVec::Constant(kNaN);
  // When both fly take-off, NMPC (the follower losing its only neighbour estimate for longer
  // than estimate_timeout: the failsafe lands it)
  // and landing, with the diagnostics after each command
  const long n = ::fnmpc::testing::CountMallocs([&] {
    for (double t = 0.0; t <= 20.0; t += kTs) {
      ControlOutput o = leader.ControlWithEstimates(t, pl.Estimate(t), {});
      leader.Diagnose(&o);
      pl.Step(o);
      estimation::VehicleEstimate e = pf.Estimate(t);
      e.position.z() -= kGround;
      nb[0].setZero();
      nb[0].head<3>() = p0 - pf.x.head<3>();
      std::vector<estimation::NeighbourStateVec>& given = nb;
      if (t > 8.0 && t < 8.6) given[0] = lost;
      ControlOutput f = follower.ControlWithEstimates(t, e, given);
      follower.Diagnose(&f);
      pf.Step(f);
    }
  });
  // Then no C allocation call was made, and both landed
  EXPECT_EQ(n, 0);
  EXPECT_EQ(leader.phase(), FlightPhase::kLanded);
  EXPECT_EQ(follower.phase(), FlightPhase::kLanded);
}

TEST(SafetyTest, NoAllocationWhenCooperativePlansAreExchanged) {
  // Given a leader and a cooperative follower built (all allocation happens here),
  ControllerConfig lc = BaseConfig(true);
  lc.compensation = Compensation::kCooperative;
  ControllerConfig fc = BaseConfig(false);
  fc.compensation = Compensation::kCooperative;
  VehicleController leader(lc), follower(fc);
  Plant pl, pf;
  std::vector<estimation::NeighbourStateVec> nb(1);
  PlanMessage m;
  int used = 0;
  // when they fly for 8 s, the leader's plan handed to the follower every step,
  const long n = ::fnmpc::testing::CountMallocs([&] {
    for (int k = 0; k * kTs <= 8.0; ++k) {
      const double t = k * kTs;
      ControlOutput o = leader.ControlWithEstimates(t, pl.Estimate(t), {});
      leader.Diagnose(&o);
      pl.Step(o);
      if (leader.MakePlan(&m) && follower.ReceivePlan(m)) ++used;
      estimation::VehicleEstimate e = pf.Estimate(t + kTs);
      e.position.z() -= kGround;
      nb[0].setZero();
      nb[0].head<3>() = pl.x.head<3>() - pf.x.head<3>();
      nb[0].segment<3>(3) = pl.x.segment<3>(3);
      ControlOutput f = follower.ControlWithEstimates(t + kTs, e, nb);
      follower.Diagnose(&f);
      pf.Step(f);
    }
  });
  // then no C allocation call was made, and the follower received and held fresh plans.
  EXPECT_EQ(n, 0);
  EXPECT_GT(used, 50);
  EXPECT_TRUE(follower.neighbour_plans().Fresh(0, 8.0 + kTs, fc.plan_timeout));
}

TEST(SafetyTest, TrackingSlotsChangeHandsWithoutAllocation) {
  // Given a follower with one formation neighbour (vehicle 0) and max_tracked 3: two slots
  // for the other vehicles in view, its own filter started by a compass reading,
  ControllerConfig fc = BaseConfig(false);
  fc.track_others = true;
  fc.max_tracked = 3;
  VehicleController c(fc);
  ASSERT_EQ(c.other_slots(), 2);
  auto measure = [&](double t, SensorKind kind, int target, double range) {
    Measurement m;
    m.kind = kind;
    m.vehicle = 1;
    m.stamp = m.arrival = t;
    m.yaw = 0.0;
    m.relative = {target, range, 0.3 * target, 0.0, 0.1};
    c.Process(m);
  };
  measure(0.0, SensorKind::kCompass, -1, kNaN);
  std::array<std::array<int, 2>, 3> slots{};  // at t = 1, 3 and 6.5 s (no allocation)
  int checks = 0;
  // When vehicles come into and leave its view (at 50 Hz): 5 (3 m) and 6 (4 m) first; from
  // 2 s 6 is gone and 7 (1.5 m) is there; from 4 s 5 is gone and 8 (5 m) is there, with
  // Control every 0.05 s,
  const long n = ::fnmpc::testing::CountMallocs([&] {
    for (int k = 1; k <= 350; ++k) {
      const double t = 0.02 * k;
      measure(t, SensorKind::kCompass, -1, kNaN);
      measure(t, SensorKind::kRelative, 0, 2.0);
      if (t < 4.0) measure(t, SensorKind::kRelative, 5, 3.0);
      if (t < 2.0) measure(t, SensorKind::kRelative, 6, 4.0);
      if (t >= 2.0) measure(t, SensorKind::kRelative, 7, 1.5);
      if (t >= 4.0) measure(t, SensorKind::kRelative, 8, 5.0);
      if (k % 5 == 0) c.Control(t);
      if (k == 50 || k == 150 || k == 325) {
        slots[checks++] = {c.tracked_vehicle(0), c.tracked_vehicle(1)};
      }
    }
  });
  // then no C allocation call was made,
  EXPECT_EQ(n, 0);
  // the first two took the slots, 7 (nearer by more than the margin) took the farthest one's
  // (6), 8 waited until 5 had been unmeasured for neighbour_timeout and took its slot.
  ASSERT_EQ(checks, 3);
  EXPECT_EQ(slots[0], (std::array<int, 2>{5, 6}));
  EXPECT_EQ(slots[1], (std::array<int, 2>{5, 7}));
  EXPECT_EQ(slots[2], (std::array<int, 2>{8, 7}));
}

TEST(SafetyTest, MaxTrackedIsChecked) {
  ControllerConfig fc = BaseConfig(false);
  fc.max_tracked = 0;
  EXPECT_THROW(VehicleController{fc}, std::invalid_argument);
  fc.max_tracked = 1;  // the formation neighbour keeps its slot; none is left for others
  fc.track_others = true;
  EXPECT_EQ(VehicleController(fc).other_slots(), 0);
}

}  // namespace
}  // namespace fnmpc::formation

namespace fnmpc::formation {
namespace {

/// Two followers whose targets are each other's start: they must swap sides through each
/// other while the (virtual, still) leader hovers. Returns the smallest CoM distance in the
/// NMPC phase and the final formation errors.
struct SwapResult {
  double min_distance = kInf;
  double error_a = kNaN, error_b = kNaN;
  long fallbacks = 0;
};
// The relative observation of `target` at p_target by an observer at p_obs with attitude
// euler_obs (core/sensors.hpp geometry), with the relative sensor's white noise of `spec`.
RelativeObservation NoisyRelative(const Vec3& p_obs, const Vec3& euler_obs, const Vec3& p_target,
                                  int target, const SensorSpec& spec, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Vec3 d =
      RotationZyx(euler_obs.x(), euler_obs.y(), euler_obs.z()).transpose() * (p_target - p_obs);
  RelativeObservation o;
  o.target = target;
  o.range = d.norm() + spec.noise[0] * (1.0 + spec.range_noise_growth * d.norm()) * n(*rng);
  o.bearing = std::atan2(d.y(), d.x()) + spec.noise[1] * n(*rng);
  o.elevation = std::asin(d.z() / d.norm()) + spec.noise[2] * n(*rng);
  o.relative_yaw = WrapAngle(-euler_obs.z() + spec.noise2[0] * n(*rng));
  return o;
}
// Two followers A (vehicle 1) and B (vehicle 2) of a leader at rest, started on the wrong
// sides: keeping the formation makes them swap through each other. noise_seed < 0: every
// estimate exact; else each follower estimates the other with a NeighbourEkf fed by the
// relative sensor (default noise) at the control instants, and the controller gets that
// estimate with its covariance (the leader's stays exact).
SwapResult FlySwap(double radius, double confidence = 0.95, int noise_seed = -1) {
  const Vec3 leader(2.0, 0.0, 1.1);
  ControllerConfig ca = BaseConfig(false), cb = BaseConfig(false);
  ca.vehicle = 1;
  cb.vehicle = 2;
  ca.safety.collision_radius = cb.safety.collision_radius = radius;
  ca.safety.collision_confidence = cb.safety.collision_confidence = confidence;
  // A starts at y = -1.5 and must end at y = +1.5 (leader offset), B the other way.
  ca.neighbours = {{0, Vec3(2.0, -1.5, 0.0)}, {2, Vec3(0.0, -3.0, 0.0)}};
  cb.neighbours = {{0, Vec3(2.0, 1.5, 0.0)}, {1, Vec3(0.0, 3.0, 0.0)}};
  VehicleController a(ca), b(cb);
  Plant pa, pb;
  pa.x[1] = -1.5;
  pb.x[1] = 1.5;
  const Vec3 a0 = pa.x.head<3>(), b0 = pb.x.head<3>();
  std::vector<estimation::NeighbourStateVec> na(2), nb(2);
  std::vector<estimation::NeighbourStateCov> ca_cov(2, estimation::NeighbourStateCov::Zero()),
      cb_cov(2, estimation::NeighbourStateCov::Zero());
  const SensorsConfig sensors;
  auto filter = [&](int observer, int target) {
    estimation::NeighbourEkfConfig c;
    c.sensors = sensors;
    c.observer = observer;
    c.target = target;
    return estimation::NeighbourEkf(c);
  };
  estimation::NeighbourEkf fa = filter(1, 2), fb = filter(2, 1);  // A's of B, B's of A
  std::mt19937 rng(static_cast<unsigned>(std::max(noise_seed, 0)));
  SwapResult r;
  Vec<9> xa_before = pa.x, xb_before = pb.x;  // the plants' states at the last instant
  for (double t = 0.0; t <= 16.0; t += kTs) {
    auto own = [&](const Plant& p, const Vec3& start) {
      estimation::VehicleEstimate e = p.Estimate(t);
      e.position -= Vec3(start.x(), start.y(), kGround);  // {m}: origin at the start
      return e;
    };
    auto rel = [](const Plant& self, const Vec3& other_p, const Vec3& other_v,
                  estimation::NeighbourStateVec* out) {
      out->setZero();
      out->head<3>() = other_p - self.x.head<3>();
      out->segment<3>(3) = other_v;
    };
    // The other follower's estimate: exact, or the filter's after the relative sensor's
    // samples (50 Hz, no latency) since the last control instant; the plants' states between
    // the instants are interpolated linearly (1 mm off at the 3.6 m/s^2 of the bound).
    auto estimate = [&](const Plant& self, const Vec<9>& self_before, const Plant& other,
                        const Vec<9>& other_before, int observer, int target,
                        estimation::NeighbourEkf* f, estimation::NeighbourStateVec* out,
                        estimation::NeighbourStateCov* cov) {
      if (noise_seed < 0) return rel(self, other.x.head<3>(), other.x.segment<3>(3), out);
      const double period = 1.0 / sensors.relative.rate_hz;
      for (double s = std::ceil((t - kTs) / period + 1e-9) * period; s <= t + 1e-9; s += period) {
        if (s < -1e-9) continue;
        const double l = std::clamp(1.0 - (t - s) / kTs, 0.0, 1.0);
        const Vec<9> xs = (1.0 - l) * self_before + l * self.x;
        const Vec<9> xo = (1.0 - l) * other_before + l * other.x;
        Measurement m;
        m.kind = SensorKind::kRelative;
        m.vehicle = observer;
        m.stamp = m.arrival = s;
        m.relative =
            NoisyRelative(xs.head<3>(), xs.tail<3>(), xo.head<3>(), target, sensors.relative, &rng);
        f->Process(m, xs.tail<3>(), xs.segment<3>(3));
      }
      f->PredictTo(t, self.x.segment<3>(3));
      const estimation::NeighbourEstimate e = f->EstimateAt(t, self.x.segment<3>(3));
      *out = e.x;
      *cov = e.covariance;
    };
    rel(pa, leader, Vec3::Zero(), &na[0]);
    estimate(pa, xa_before, pb, xb_before, 1, 2, &fa, &na[1], &ca_cov[1]);
    rel(pb, leader, Vec3::Zero(), &nb[0]);
    estimate(pb, xb_before, pa, xa_before, 2, 1, &fb, &nb[1], &cb_cov[1]);
    const ControlOutput oa = a.ControlWithEstimates(t, own(pa, a0), na, &ca_cov);
    const ControlOutput ob = b.ControlWithEstimates(t, own(pb, b0), nb, &cb_cov);
    xa_before = pa.x;
    xb_before = pb.x;
    pa.Step(oa);
    pb.Step(ob);
    if (a.phase() == FlightPhase::kNmpc && b.phase() == FlightPhase::kNmpc)
      r.min_distance = std::min(r.min_distance, (pa.x.head<3>() - pb.x.head<3>()).norm());
  }
  r.error_a = ((leader - pa.x.head<3>()) - ca.neighbours[0].desired).norm();
  r.error_b = ((leader - pb.x.head<3>()) - cb.neighbours[0].desired).norm();
  r.fallbacks = a.fallbacks() + b.fallbacks();
  return r;
}

TEST(SafetyTest, FollowersSwappingSidesKeepTheCollisionRadius) {
  // Without collision avoidance they fly through each other
  const SwapResult off = FlySwap(0.0);
  EXPECT_LT(off.min_distance, 0.1);
  // With it they give way to their right and keep r_min (5 cm of slack for the soft
  // constraint), then end in formation
  const double r = 0.45;
  const SwapResult on = FlySwap(r);
  std::printf("[   INFO   ] swap: min distance %.3f m without, %.3f m with r_min %.2f m\n",
              off.min_distance, on.min_distance, r);
  EXPECT_GE(on.min_distance, r - 0.05);
  EXPECT_LT(on.error_a, 0.05);
  EXPECT_LT(on.error_b, 0.05);
  EXPECT_EQ(on.fallbacks, 0);
}

TEST(SafetyTest, SwapOnNoisyRelativeEstimatesKeepsTheCollisionRadius) {
  // Given the swap with each follower's estimate of the other from its NeighbourEkf on the
  // default relative sensor's noise (both filters lag the swap's accelerations), 5 seeds
  const double r = 0.45;
  for (int seed = 1; seed <= 5; ++seed) {
    // When the collision rows keep r_min on the estimates alone (confidence 0.5) and with
    // the chance constraint's margin (0.95: 1.645 standard deviations of the prediction)
    const SwapResult plain = FlySwap(r, 0.5, seed);
    const SwapResult chance = FlySwap(r, 0.95, seed);
    std::printf(
        "[   INFO   ] seed %d: min distance %.3f m on the estimates, %.3f m with the "
        "margin\n",
        seed, plain.min_distance, chance.min_distance);
    // Then the margin keeps them farther apart, within r_min - 0.05 m, and both end in
    // formation without a fallback
    EXPECT_GT(chance.min_distance, plain.min_distance) << "seed " << seed;
    EXPECT_GE(chance.min_distance, r - 0.05) << "seed " << seed;
    EXPECT_LT(chance.error_a, 0.05) << "seed " << seed;
    EXPECT_LT(chance.error_b, 0.05) << "seed " << seed;
    EXPECT_EQ(chance.fallbacks, 0) << "seed " << seed;
  }
}

}  // namespace
}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
// Cooperative mode (Compensation::kCooperative): a neighbour's plan anchored at
// the receiver's relative estimate and shifted by its age, the fallback to constant velocity
// when it is late or lost (no allocation: safety_test.cpp, with the malloc counter).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "fnmpc/formation/neighbour_plan.hpp"
#include "tests/formation/controller_test_support.hpp"

namespace fnmpc::formation {
namespace {

using testing::BaseConfig;
using testing::kGround;
using testing::kTs;
using testing::Plant;

/// A plan of vehicle 0 stamped at `stamp`: accelerating at 2 m/s^2 in z from 0.1 m/s in x,
/// thrust 10 + k N at point k, 16 points kTs apart.
PlanMessage AcceleratingPlan(double stamp) {
  PlanMessage m;
  m.vehicle = 0;
  m.stamp = stamp;
  m.sample_time = kTs;
  m.points = 16;
  for (int k = 0; k < m.points; ++k) {
    const double s = k * kTs;
    m.displacement[k] = Vec3(0.1 * s, 0.0, s * s);
    m.velocity[k] = Vec3(0.1, 0.0, 2.0 * s);
    m.thrust[k] = 10.0 + k;
  }
  m.disturbance = Vec3(0.0, 0.0, -1.0);
  return m;
}

TEST(NeighbourPlansTest, AnchorsAtTheRelativeEstimateAndShiftsByTheAge) {
  // Given a neighbour's plan stamped at 1.0 s, received by a follower whose current estimate
  // of the neighbour is rel_now,
  NeighbourPlans plans({0});
  ASSERT_TRUE(plans.Receive(AcceleratingPlan(1.0)));
  const Vec3 rel_now(1.0, -2.0, 0.5), vel_now(0.3, 0.0, -0.1);
  const PlanMessage m = AcceleratingPlan(1.0);
  PlanPrediction p;
  // When it predicts at t = 1.1 s (age two points) 0.15 s ahead (three points),
  ASSERT_TRUE(plans.Predict(0, 1.1, 0.15, 0.2, rel_now, vel_now, &p));
  // then the plan's displacement from age to age + tau is added to the anchor, and its
  // change of velocity to the velocity estimate, with the plan's thrust there,
  EXPECT_LT((p.rel - (rel_now + m.displacement[5] - m.displacement[2])).norm(), 1e-12);
  EXPECT_LT((p.vel - (vel_now + m.velocity[5] - m.velocity[2])).norm(), 1e-12);
  EXPECT_NEAR(p.thrust, 15.0, 1e-12);
  // at tau = 0 the prediction is the anchor itself (the plan's origin is never used),
  ASSERT_TRUE(plans.Predict(0, 1.1, 0.0, 0.2, rel_now, vel_now, &p));
  EXPECT_LT((p.rel - rel_now).norm(), 1e-12);
  EXPECT_LT((p.vel - vel_now).norm(), 1e-12);
  // between points it interpolates (age + tau = 0.125 s: halfway between points 2 and 3),
  ASSERT_TRUE(plans.Predict(0, 1.1, 0.025, 0.2, rel_now, vel_now, &p));
  EXPECT_NEAR(p.thrust, 12.5, 1e-12);
  EXPECT_NEAR(p.vel.z(), vel_now.z() + 2.0 * 0.025, 1e-12);
  EXPECT_NEAR(p.rel.z(), rel_now.z() + 0.5 * (0.1 * 0.1 + 0.15 * 0.15) - 0.1 * 0.1, 1e-12);
  // and beyond its last point (0.75 s) it goes on at the last velocity.
  ASSERT_TRUE(plans.Predict(0, 1.1, 1.0, 0.2, rel_now, vel_now, &p));
  const Vec3 end = m.displacement[15] + (1.1 - 0.75) * m.velocity[15];
  EXPECT_LT((p.rel - (rel_now + end - m.displacement[2])).norm(), 1e-12);
  EXPECT_LT((p.vel - (vel_now + m.velocity[15] - m.velocity[2])).norm(), 1e-12);
}

TEST(NeighbourPlansTest, LateLostOrInvalidPlansAreNotUsed) {
  NeighbourPlans plans({0, 3});
  PlanPrediction p;
  // No plan yet: nothing to predict from,
  EXPECT_FALSE(plans.Predict(0, 1.0, 0.0, 0.2, Vec3::Zero(), Vec3::Zero(), &p));
  ASSERT_TRUE(plans.Receive(AcceleratingPlan(1.0)));
  // fresh up to max_age, late after it,
  EXPECT_TRUE(plans.Fresh(0, 1.2, 0.2));
  EXPECT_FALSE(plans.Fresh(0, 1.2001, 0.2));
  EXPECT_FALSE(plans.Predict(0, 1.3, 0.0, 0.2, Vec3::Zero(), Vec3::Zero(), &p));
  EXPECT_FALSE(plans.Fresh(1, 1.1, 0.2));  // the other neighbour has sent nothing
  // an older or repeated plan does not replace the one held, a newer one does,
  EXPECT_FALSE(plans.Receive(AcceleratingPlan(0.9)));
  EXPECT_FALSE(plans.Receive(AcceleratingPlan(1.0)));
  EXPECT_TRUE(plans.Receive(AcceleratingPlan(1.05)));
  EXPECT_DOUBLE_EQ(plans.plan(0).stamp, 1.05);
  // and plans of a vehicle that is no neighbour, or with a non-finite entry, are refused.
  PlanMessage other = AcceleratingPlan(2.0);
  other.vehicle = 7;
  EXPECT_FALSE(plans.Receive(other));
  PlanMessage bad = AcceleratingPlan(2.0);
  bad.displacement[7].y() = kNaN;
  EXPECT_FALSE(plans.Receive(bad));
  bad = AcceleratingPlan(2.0);
  bad.points = 1;
  EXPECT_FALSE(plans.Receive(bad));
  EXPECT_DOUBLE_EQ(plans.plan(0).stamp, 1.05);
  plans.Clear();
  EXPECT_FALSE(plans.Fresh(0, 1.05, 0.2));
}

/// A follower flown on the NMPC's own model with the neighbour (vehicle 0) hovering at
/// p0; `plan_for(t)` is called before each control step and may hand it a plan.
template <class PlanFor>
std::vector<ControlOutput> FlyFollower(Compensation level, const PlanFor& plan_for) {
  ControllerConfig fc = BaseConfig(false);
  fc.compensation = level;
  VehicleController c(fc);
  Plant pf;
  const Vec3 p0(1.3, -0.8, 1.9);
  std::vector<estimation::NeighbourStateVec> nb(1);
  std::vector<ControlOutput> out;
  PlanMessage m;
  for (int k = 0; k * kTs <= 8.0; ++k) {
    const double t = k * kTs;
    if (plan_for(t, &m)) c.ReceivePlan(m);
    estimation::VehicleEstimate e = pf.Estimate(t);
    e.position.z() -= kGround;
    nb[0].setZero();
    nb[0].head<3>() = p0 - pf.x.head<3>();
    out.push_back(c.ControlWithEstimates(t, e, nb));
    pf.Step(out.back());
  }
  return out;
}

bool SameCommands(const std::vector<ControlOutput>& a, const std::vector<ControlOutput>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (a[k].thrust != b[k].thrust || a[k].roll != b[k].roll || a[k].pitch != b[k].pitch) {
      return false;
    }
  }
  return true;
}

TEST(CooperativeTest, FallsBackToWakeWhenPlansAreLostOrLate) {
  // Given a follower flown with `wake`,
  const auto none = [](double, PlanMessage*) { return false; };
  const std::vector<ControlOutput> wake = FlyFollower(Compensation::kWake, none);
  ASSERT_EQ(wake.back().phase, FlightPhase::kNmpc);
  // when the same flight is flown `cooperative` with every plan lost, or every plan arriving
  // older than plan_timeout (0.2 s), then the commands are the wake level's, bit for bit;
  EXPECT_TRUE(SameCommands(wake, FlyFollower(Compensation::kCooperative, none)));
  const auto late = [](double t, PlanMessage* m) {
    *m = AcceleratingPlan(t - 0.25);
    return true;
  };
  EXPECT_TRUE(SameCommands(wake, FlyFollower(Compensation::kCooperative, late)));
  // fresh plans (the neighbour accelerating upwards) change them,
  const auto fresh = [](double t, PlanMessage* m) {
    *m = AcceleratingPlan(t - 0.05);
    return true;
  };
  const std::vector<ControlOutput> coop = FlyFollower(Compensation::kCooperative, fresh);
  EXPECT_FALSE(SameCommands(wake, coop));
  // and the follower climbs earlier to keep its offset below the rising neighbour.
  double wake_thrust = 0.0, coop_thrust = 0.0;
  for (std::size_t k = 0; k < coop.size(); ++k) {
    if (!coop[k].nmpc) continue;
    wake_thrust += wake[k].thrust;
    coop_thrust += coop[k].thrust;
  }
  EXPECT_GT(coop_thrust, wake_thrust);
  // A plan is used by `cooperative` only: `wake` ignores fresh plans.
  EXPECT_TRUE(SameCommands(wake, FlyFollower(Compensation::kWake, fresh)));
}

TEST(CooperativeTest, PublishesItsPlanFromTheNmpcPhaseOn) {
  // Given a leader flown from the ground,
  ControllerConfig lc = BaseConfig(true);
  lc.compensation = Compensation::kCooperative;
  VehicleController leader(lc);
  Plant pl;
  PlanMessage m;
  bool before = false;
  for (int k = 0; k * kTs <= 8.0; ++k) {
    const double t = k * kTs;
    const ControlOutput o = leader.ControlWithEstimates(t, pl.Estimate(t), {});
    pl.Step(o);
    // then it has no plan to publish before its NMPC phase,
    if (!o.nmpc) before = before || leader.MakePlan(&m);
  }
  EXPECT_FALSE(before);
  // and one in it: stamped now, horizon + 1 points from zero displacement, its velocity and
  // thrust, valid.
  ASSERT_EQ(leader.phase(), FlightPhase::kNmpc);
  ASSERT_TRUE(leader.MakePlan(&m));
  EXPECT_EQ(m.vehicle, 0);
  EXPECT_NEAR(m.stamp, 160 * kTs, 1e-9);
  EXPECT_EQ(m.points, lc.rti.horizon + 1);
  EXPECT_DOUBLE_EQ(m.sample_time, lc.rti.sample_time);
  EXPECT_EQ(m.displacement[0], Vec3::Zero());
  EXPECT_LT((m.velocity[0] - pl.x.segment<3>(3)).norm(), 0.2);
  EXPECT_NEAR(m.thrust[0], lc.params.mass * kGravity, 0.2 * lc.params.mass * kGravity);
  EXPECT_TRUE(m.Valid());
}

}  // namespace
}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
// Controller compensation levels: `none` is the controller without the
// disturbance estimate, `observer` removes the steady offset a constant external force
// leaves; `wake` predicts a neighbour's wake; an unknown name is refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/model/wake_force.hpp"
#include "tests/formation/controller_test_support.hpp"

namespace fnmpc::formation {
namespace {

using testing::BaseConfig;
using testing::kGround;
using testing::kTs;
using testing::Plant;

// The NMPC's model as plant plus a constant external acceleration d (a wind or a wake
// pushing the vehicle); the estimate reports d as the observer would once converged.
struct PushedPlant {
  Plant plant;
  Vec3 d = Vec3::Zero();
  void Step(const ControlOutput& u) {
    const Vec3 in(u.thrust, u.roll, u.pitch);
    const double h = kTs / 10;
    for (int i = 0; i < 10; ++i) {
      Vec<9>& x = plant.x;
      x = model::Rk4<model::QuadrotorModel>(x, in, u.yaw, model::AttitudeModelParams{}, h, 1);
      // The exact double integral of d over the sub-step (v' gains d, nothing else changes).
      x.head<3>() += 0.5 * h * h * d;
      x.segment<3>(3) += h * d;
      if (x[2] < kGround) {
        x[2] = kGround;
        x.segment<3>(3).setZero();
      }
    }
  }
  [[nodiscard]] estimation::VehicleEstimate Estimate(double t) const {
    estimation::VehicleEstimate e = plant.Estimate(t);
    e.disturbance = d;
    return e;
  }
};

// Flies a leader holding its hover point for `until` s under d; returns the final position
// error from the hover point the NMPC engaged at.
double HoverError(Compensation level, const Vec3& d, double until) {
  ControllerConfig cfg = BaseConfig(true);
  cfg.compensation = level;
  VehicleController c(cfg);
  PushedPlant p;
  for (int k = 0; k * kTs <= until; ++k) {
    // The push starts once the NMPC holds the hover point (the PID take-off has no model).
    p.d = c.phase() == FlightPhase::kNmpc && k * kTs > 4.0 ? d : Vec3(Vec3::Zero());
    const ControlOutput o = c.ControlWithEstimates(k * kTs, p.Estimate(k * kTs), {});
    p.Step(o);
  }
  EXPECT_EQ(c.phase(), FlightPhase::kNmpc);
  EXPECT_EQ(c.fallbacks(), 0);
  return (p.plant.x.head<3>() - c.anchor()).norm();
}

TEST(CompensationTest, ObserverRemovesTheSteadyOffsetOfAConstantForce) {
  // Given a hovering leader pushed by 0.4 m/s^2 sideways and 0.6 m/s^2 down (0.55 N and
  // 0.8 N on 1.37 kg: a wind, a wake) from t = 4 s
  const Vec3 d(0.4, -0.3, -0.6);
  // When it holds its hover point for 10 s more with each level
  const double none = HoverError(Compensation::kNone, d, 14.0);
  const double observer = HoverError(Compensation::kObserver, d, 14.0);
  std::printf("[compensation] steady hover error: none %.4f m, observer %.5f m\n", none, observer);
  // Then without compensation an offset remains, with the observer's d it is gone
  EXPECT_GT(none, 0.02);
  EXPECT_LT(observer, 1e-3);
}

TEST(CompensationTest, NoneIgnoresTheDisturbanceEstimate) {
  // Given two leaders with compensation none, flown on the same estimates except d
  ControllerConfig cfg = BaseConfig(true);
  cfg.compensation = Compensation::kNone;
  VehicleController a(cfg), b(cfg);
  Plant plant;
  bool any_nmpc = false;
  for (int k = 0; k * kTs <= 6.0; ++k) {
    estimation::VehicleEstimate e = plant.Estimate(k * kTs);
    e.disturbance = Vec3::Zero();
    const ControlOutput oa = a.ControlWithEstimates(k * kTs, e, {});
    e.disturbance = Vec3(1.0, -2.0, 3.0);
    const ControlOutput ob = b.ControlWithEstimates(k * kTs, e, {});
    // Then every command is the same, bit for bit
    ASSERT_EQ(oa.thrust, ob.thrust) << k;
    ASSERT_EQ(oa.roll, ob.roll) << k;
    ASSERT_EQ(oa.pitch, ob.pitch) << k;
    if (oa.nmpc) {
      any_nmpc = true;
      EXPECT_EQ(oa.disturbance, Vec3::Zero());
    }
    plant.Step(oa);
  }
  EXPECT_TRUE(any_nmpc);
}

TEST(CompensationTest, ObserverNeverPredictsWithANonFiniteEstimate) {
  // Given a hovering leader with the observer whose d estimate turns NaN
  ControllerConfig cfg = BaseConfig(true);
  cfg.compensation = Compensation::kObserver;
  VehicleController c(cfg);
  Plant plant;
  for (int k = 0; k * kTs <= 6.0; ++k) {
    estimation::VehicleEstimate e = plant.Estimate(k * kTs);
    e.disturbance = k * kTs > 5.0 ? Vec3(kNaN, 0.0, 0.0) : Vec3(0.1, 0.0, 0.0);
    const ControlOutput o = c.ControlWithEstimates(k * kTs, e, {});
    // Then the commands stay finite, and the NaN estimate is replaced by zero
    ASSERT_TRUE(std::isfinite(o.thrust) && std::isfinite(o.roll) && std::isfinite(o.pitch));
    if (o.nmpc && k * kTs > 5.0) {
      EXPECT_EQ(o.disturbance, Vec3::Zero());
    }
    if (o.nmpc && k * kTs <= 5.0) {
      EXPECT_EQ(o.disturbance, Vec3(0.1, 0.0, 0.0));
    }
    plant.Step(o);
  }
  EXPECT_EQ(c.phase(), FlightPhase::kNmpc);
}

// A follower flying 1.5 m sideways into the wake of a neighbour hovering 0.8 m above its
// target (the plant pushed by the controller's own wake model: a perfect model), with an
// observer emulated as a first-order lag (0.5 s, VehicleEkf's default) of what d estimates: the
// whole push with `observer`, the push minus the model's known part (none here) with `wake`.
// Returns the largest and the final height error [m] after the NMPC took over.
struct WakeFlight {
  double max_error = 0.0, final_error = 0.0;
  long fallbacks = 0;
};
WakeFlight FlyIntoWake(Compensation level) {
  ControllerConfig cfg = BaseConfig(false);
  cfg.compensation = level;
  cfg.neighbours = {{0, Vec3(0.0, 0.0, 0.8)}};
  VehicleController c(cfg);
  const model::WakeForceModel wake(cfg.params);
  const double thrust = cfg.params.mass * kGravity;
  PushedPlant p;
  p.plant.x[0] = -1.5;
  const Vec3 p0(0.0, 0.0, 1.8);  // the neighbour, hovering
  std::vector<estimation::NeighbourStateVec> nb(1);
  Vec3 d_estimate = Vec3::Zero();
  WakeFlight out;
  for (int k = 0; k * kTs <= 16.0; ++k) {
    const double t = k * kTs;
    const Vec3 push(0.0, 0.0, wake.Acceleration(p.plant.x.head<3>() - p0, thrust));
    p.d = push;
    // (with `wake` the estimator is told the model's part, here all of the push)
    const Vec3 seen = level >= Compensation::kWake ? Vec3(Vec3::Zero()) : push;
    d_estimate += (seen - d_estimate) * (kTs / 0.5);
    estimation::VehicleEstimate e = p.Estimate(t);
    e.disturbance = d_estimate;
    e.position.z() -= kGround;
    nb[0].setZero();
    nb[0].head<3>() = p0 - p.plant.x.head<3>();
    const ControlOutput o = c.ControlWithEstimates(t, e, nb);
    EXPECT_TRUE(std::isfinite(o.thrust) && std::isfinite(o.roll) && std::isfinite(o.pitch));
    if (o.nmpc) {
      const double err = std::abs(p.plant.x.z() - (p0.z() - 0.8));
      out.max_error = std::max(out.max_error, err);
      out.final_error = err;
      // The wake part is reported (and told to the estimator) only at level wake
      if (level < Compensation::kWake) {
        EXPECT_EQ(o.wake, Vec3::Zero());
      }
    }
    p.Step(o);
  }
  EXPECT_EQ(c.phase(), FlightPhase::kNmpc);
  out.fallbacks = c.fallbacks();
  return out;
}

TEST(CompensationTest, WakeLevelPredictsTheWakeItFliesInto) {
  // Given a follower that flies into a hovering neighbour's wake with each level
  const WakeFlight none = FlyIntoWake(Compensation::kNone);
  const WakeFlight observer = FlyIntoWake(Compensation::kObserver);
  const WakeFlight wake = FlyIntoWake(Compensation::kWake);
  std::printf(
      "[compensation] into the wake, max / final height error: none %.3f / %.3f m, "
      "observer %.3f / %.3f m, wake %.3f / %.3f m\n",
      none.max_error, none.final_error, observer.max_error, observer.final_error, wake.max_error,
      wake.final_error);
  // Then without compensation the push leaves an offset, the observer removes it after a lag,
  // and the wake level, which predicts the push before the observer sees it, sags less on the
  // way in and ends as close
  EXPECT_GT(none.final_error, 0.05);
  EXPECT_LT(observer.final_error, 0.01);
  EXPECT_LT(wake.final_error, 0.01);
  EXPECT_LT(wake.max_error, observer.max_error);
  EXPECT_EQ(wake.fallbacks, 0);
}

TEST(CompensationTest, EveryLevelIsAcceptedAndNamed) {
  for (Compensation level : {Compensation::kNone, Compensation::kObserver, Compensation::kWake,
                             Compensation::kCooperative}) {
    ControllerConfig cfg = BaseConfig(false);
    cfg.compensation = level;
    EXPECT_NO_THROW(VehicleController{cfg}) << ToString(level);
  }
  ControllerConfig cfg = BaseConfig(false);
  cfg.plan_timeout = 0.0;
  EXPECT_THROW(VehicleController{cfg}, std::invalid_argument);
  // And the names map one to one (the YAML key and the CLI use them)
  int index = -1;
  EXPECT_TRUE(kCompensationChoice.Check("observer", &index).empty());
  EXPECT_EQ(index, static_cast<int>(Compensation::kObserver));
  EXPECT_TRUE(kCompensationChoice.Check("wake", &index).empty());
  EXPECT_EQ(index, static_cast<int>(Compensation::kWake));
  EXPECT_TRUE(kCompensationChoice.Check("cooperative", &index).empty());
  EXPECT_EQ(index, static_cast<int>(Compensation::kCooperative));
  EXPECT_NE(kCompensationChoice.Check("full", &index)
                .find("must be one of none, observer, wake, cooperative"),
            std::string::npos);
}

}  // namespace
}  // namespace fnmpc::formation

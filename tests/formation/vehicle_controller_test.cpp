// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/vehicle_controller.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "fnmpc/formation/throttle_map.hpp"
#include "tests/formation/controller_test_support.hpp"

namespace fnmpc::formation {
namespace {

using testing::BaseConfig;
using testing::Fly;
using testing::kGround;
using testing::kTs;
using testing::Plant;
using testing::Vehicle;

TEST(VehicleControllerTest, TakeoffSwitchToNmpcHasNoJump) {
  // Given a leader on the ground with perfect estimates
  VehicleController c(BaseConfig(true));
  Plant plant;
  // When it takes off by PID, hovers and switches to the NMPC
  const auto out = Fly(&c, &plant, 8.0);
  std::size_t sw = 0;
  for (std::size_t k = 1; k < out.size(); ++k) {
    if (out[k].phase == FlightPhase::kNmpc && out[k - 1].phase == FlightPhase::kTakeoff) sw = k;
  }
  ASSERT_GT(sw, 0U) << "never switched to the NMPC";
  // Then the first NMPC-phase command equals the PID's last command exactly
  EXPECT_EQ(out[sw].thrust, out[sw - 1].thrust);
  EXPECT_EQ(out[sw].roll, out[sw - 1].roll);
  EXPECT_EQ(out[sw].pitch, out[sw - 1].pitch);
  EXPECT_TRUE(out[sw].nmpc);
  // and the commands move smoothly through the blend (no step larger than in normal flight)
  for (std::size_t k = sw; k < out.size() && k < sw + 40; ++k) {
    EXPECT_LT(std::abs(out[k].thrust - out[k - 1].thrust), 0.5) << k;
    EXPECT_LT(std::abs(out[k].roll - out[k - 1].roll), 0.02) << k;
    EXPECT_LT(std::abs(out[k].pitch - out[k - 1].pitch), 0.02) << k;
  }
  // and the NMPC holds the take-off height with no fallback
  EXPECT_NEAR(plant.x[2], 1.0, 0.05);
  EXPECT_LT(plant.x.segment<3>(3).norm(), 0.05);
  EXPECT_EQ(c.fallbacks(), 0);
}

TEST(VehicleControllerTest, ThrottleFollowsMeasuredBatteryVoltage) {
  // Given a hovering leader
  VehicleController c(BaseConfig(true));
  Plant plant;
  Fly(&c, &plant, 6.0);
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  Measurement bat;
  bat.kind = SensorKind::kBattery;
  bat.vehicle = 0;
  double t = 6.05;
  // When the measured voltage drops from 16.5 V to 14.5 V
  std::vector<double> throttle, thrust;
  for (double v : {16.5, 14.5}) {
    bat.stamp = bat.arrival = t;
    bat.voltage = v;
    c.Process(bat);
    const ControlOutput o = c.ControlWithEstimates(t, plant.Estimate(t), {});
    plant.Step(o);
    t += kTs;
    // Then the throttle produces the commanded thrust at that voltage
    ASSERT_TRUE(std::isfinite(o.throttle));
    EXPECT_NEAR(ThrottleToThrust(Vehicle().throttle, o.throttle, v), o.thrust, 1e-6);
    throttle.push_back(o.throttle);
    thrust.push_back(o.thrust);
  }
  // and the lower voltage needs a higher throttle for (about) the same hover thrust
  EXPECT_NEAR(thrust[0], thrust[1], 0.2);
  EXPECT_GT(throttle[1], throttle[0] + 0.02);
}

TEST(VehicleControllerTest, NaNEstimateNeverBecomesACommand) {
  // Given a leader in NMPC hover and one taking off
  VehicleController c(BaseConfig(true));
  Plant plant;
  Fly(&c, &plant, 6.0);
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  VehicleController t(BaseConfig(true));
  Plant plant2;
  Fly(&t, &plant2, 1.5);
  ASSERT_EQ(t.phase(), FlightPhase::kTakeoff);
  // When their estimates turn NaN (velocity, then everything)
  for (int k = 0; k < 5; ++k) {
    estimation::VehicleEstimate e = plant.Estimate(6.05 + k * kTs);
    e.velocity.x() = kNaN;
    if (k >= 2) e.position.setConstant(kNaN);
    const ControlOutput o = c.ControlWithEstimates(6.05 + k * kTs, e, {});
    const ControlOutput p = t.ControlWithEstimates(1.55 + k * kTs, e, {});
    // Then every command stays finite and within the bounds;
    for (const ControlOutput& x : {o, p}) {
      EXPECT_TRUE(std::isfinite(x.thrust) && std::isfinite(x.roll) && std::isfinite(x.pitch));
      EXPECT_GE(x.thrust, 0.0);
      EXPECT_LE(x.thrust, 25.0);
      EXPECT_LE(std::abs(x.roll), 0.35);
    }
    // the NMPC does not run on an unusable estimate: level attitude, hover thrust (no
    // motion capture to damp with here)
    EXPECT_FALSE(o.nmpc);
    EXPECT_DOUBLE_EQ(o.thrust, 1.37 * 9.81);
    EXPECT_EQ(o.roll, 0.0);
    EXPECT_EQ(o.pitch, 0.0);
    EXPECT_EQ(o.phase, FlightPhase::kNmpc);  // shorter than the ladder's estimate_timeout
    EXPECT_TRUE(p.guarded);
  }
  EXPECT_EQ(c.fallbacks(), 0);
  // And once the estimate is valid again the NMPC recovers without fallback
  const ControlOutput r = c.ControlWithEstimates(6.4, plant.Estimate(6.4), {});
  EXPECT_FALSE(r.fallback);
  EXPECT_NEAR(r.thrust, 1.37 * 9.81, 1.0);
}

TEST(VehicleControllerTest, FollowerReachesFormationFromRelativeEstimates) {
  // Given a follower whose only neighbour hovers still at p_n, and perfect own estimates in {m}
  VehicleController c(BaseConfig(false));
  Plant plant;
  const Vec3 p_n(1.3, -0.8, 1.1);
  std::vector<estimation::NeighbourStateVec> nb(1);
  ControlOutput o;
  // When it takes off and flies by relative estimates only (own position not given)
  for (int k = 0; k * kTs <= 14.0; ++k) {
    estimation::VehicleEstimate e = plant.Estimate(k * kTs);
    nb[0].setZero();
    nb[0].head<3>() = p_n - plant.x.head<3>();
    if (c.phase() != FlightPhase::kTakeoff && c.phase() != FlightPhase::kIdle) {
      e.position.setConstant(kNaN);  // a follower's NMPC never needs it
    } else {
      e.position.z() -= kGround;  // {m}: origin at the start
    }
    o = c.ControlWithEstimates(k * kTs, e, nb);
    plant.Step(o);
  }
  // Then it holds the desired relative position d = p_n - p within 2 cm, without fallback
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  EXPECT_LT(((p_n - plant.x.head<3>()) - Vec3(1.0, -1.0, 0.0)).norm(), 0.02);
  EXPECT_EQ(c.fallbacks(), 0);
}

TEST(VehicleControllerTest, FollowerWithEightNeighboursReachesTheirMeanTarget) {
  // Given a follower with eight neighbours hovering still, whose desired offsets are not
  // consistent with one point (each off by up to 0.3 m)
  ControllerConfig cfg = BaseConfig(false);
  const Vec3 p_goal(0.4, 0.3, 1.2);  // where the offsets' mean places the follower
  std::vector<Vec3> p_n;
  cfg.neighbours.clear();
  Vec3 mean_error = Vec3::Zero();
  for (int j = 0; j < kMaxNeighbours; ++j) {
    const double a = 2.0 * std::numbers::pi * j / kMaxNeighbours;
    p_n.push_back(p_goal + Vec3(2.0 * std::cos(a), 2.0 * std::sin(a), 0.3 * (j % 2)));
    const Vec3 error(0.3 * std::sin(3.0 * a), 0.3 * std::cos(5.0 * a), 0.1 * std::sin(a));
    mean_error += error / kMaxNeighbours;
    cfg.neighbours.push_back({j + 2, Vec3(p_n.back() - p_goal + error)});
  }
  VehicleController c(cfg);
  Plant plant;
  std::vector<estimation::NeighbourStateVec> nb(kMaxNeighbours);
  // When it flies by relative estimates only
  for (int k = 0; k * kTs <= 14.0; ++k) {
    estimation::VehicleEstimate e = plant.Estimate(k * kTs);
    for (int j = 0; j < kMaxNeighbours; ++j) {
      nb[j].setZero();
      nb[j].head<3>() = p_n[j] - plant.x.head<3>();
    }
    if (c.phase() != FlightPhase::kTakeoff && c.phase() != FlightPhase::kIdle) {
      e.position.setConstant(kNaN);
    } else {
      e.position.z() -= kGround;
    }
    plant.Step(c.ControlWithEstimates(k * kTs, e, nb));
  }
  // Then it settles where the per-neighbour least-squares cost is least: the goal moved by
  // minus the offsets' mean error, within 2 cm, without fallback
  ASSERT_EQ(c.phase(), FlightPhase::kNmpc);
  EXPECT_LT((plant.x.head<3>() - (p_goal - mean_error)).norm(), 0.02);
  EXPECT_EQ(c.fallbacks(), 0);
}

TEST(VehicleControllerTest, InvalidConfigIsRejected) {
  ControllerConfig c = BaseConfig(false);
  c.neighbours.clear();
  EXPECT_THROW(VehicleController{c}, std::invalid_argument);
  c = BaseConfig(false);
  c.neighbours.push_back(c.neighbours.front());  // listed twice
  EXPECT_THROW(VehicleController{c}, std::invalid_argument);
  c = BaseConfig(false);
  c.neighbours.assign(kMaxNeighbours + 1, {0, Vec3::Zero()});
  for (int j = 0; j <= kMaxNeighbours; ++j) c.neighbours[j].vehicle = j + 2;
  EXPECT_THROW(VehicleController{c}, std::invalid_argument);
  c = BaseConfig(true);
  c.takeoff_height = 0.05;
  EXPECT_THROW(VehicleController{c}, std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::formation

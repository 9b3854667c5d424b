// SPDX-License-Identifier: BSD-3-Clause
// Rotor aerodynamics and the advected, fluctuating wake against their cited closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "fnmpc/sim/rotor_aero.hpp"
#include "fnmpc/sim/wake.hpp"
#include "fnmpc/sim/world.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

TEST(RotorAeroTest, AxialInflowThrustFollowsCombinedBladeElementMomentumTheory) {
  // Given the shipped vehicle's rotor at hover (T0 = 1.37 g / 4, T_k = 9.803e-8 N/rpm^2),
  const RotorBlade b;
  const double t0 = 1.37 * 9.81 / 4.0;
  const double omega = std::sqrt(t0 / 9.803e-8) * 2.0 * M_PI / 60.0;
  const double tip = omega * b.radius;
  const double area = M_PI * b.radius * b.radius;
  const double ct0 = t0 / (b.air_density * area * tip * tip);
  const double sa = b.solidity * b.lift_slope;
  const double lambda_h = std::sqrt(ct0 / 2.0);
  const double theta = 3.0 * (2.0 * ct0 / sa + 0.5 * lambda_h);
  // Then in still air the thrust is the identified one,
  EXPECT_DOUBLE_EQ(AxialInflowThrustRatio(b, t0, omega, 0.0), 1.0);
  double previous = 2.0;
  for (double vc : {-1.0, 0.0, 1.0, 2.0, 4.0, 6.0}) {
    const double ratio = AxialInflowThrustRatio(b, t0, omega, vc);
    const double ct = ratio * ct0;
    // and in climb inflow the thrust coefficient satisfies both momentum theory,
    // C_T = 2 lambda_i (lambda_c + lambda_i), and blade-element theory,
    // C_T = (sigma a / 2) (theta / 3 - lambda / 2) (Leishman 2006, ch. 2 and 3),
    const double lambda_c = vc / tip;
    const double lambda = 2.0 * (theta / 3.0 - 2.0 * ct / sa);
    EXPECT_NEAR(ct, 2.0 * (lambda - lambda_c) * lambda, 1e-12) << "V_c " << vc;
    // and it falls monotonically with the climb velocity.
    EXPECT_LT(ratio, previous);
    previous = ratio;
  }
  // Zero thrust at lambda_c = 2 theta / 3, i.e. at the advance ratio J = pi lambda_c.
  EXPECT_NEAR(AxialInflowThrustRatio(b, t0, omega, 2.0 * theta / 3.0 * tip), 0.0, 1e-12);
  EXPECT_GT(AxialInflowThrustRatio(b, t0, omega, 0.99 * 2.0 * theta / 3.0 * tip), 0.0);
}

TEST(RotorAeroTest, GroundEffectIsCheesemanBennett) {
  // T_IGE / T_OGE = 1 / (1 - (R / 4z)^2): z = R -> 16/15, z = 2R -> 64/63, capped at z = R/2.
  EXPECT_NEAR(GroundEffectRatio(0.127, 0.127), 16.0 / 15.0, 1e-12);
  EXPECT_NEAR(GroundEffectRatio(0.127, 0.254), 64.0 / 63.0, 1e-12);
  EXPECT_NEAR(GroundEffectRatio(0.127, 0.01), 4.0 / 3.0, 1e-12);
  EXPECT_NEAR(GroundEffectRatio(0.127, 10.0), 1.0, 2e-5);
}

TEST(RotorAeroTest, RotorDragIsLinearInTheInPlaneVelocity) {
  const Vec3 axis = Vec3::UnitZ();
  const Vec3 f = RotorDrag(0.5, 1.4, 1.0, axis, Vec3(2.0, -1.0, 5.0));
  EXPECT_NEAR(f.x(), 0.25 * 1.4 * 0.5 * 2.0, 1e-12);
  EXPECT_NEAR(f.y(), -0.25 * 1.4 * 0.5, 1e-12);
  EXPECT_EQ(f.z(), 0.0);  // axial flow makes no rotor drag
}

TEST(WakeTest, TravelTimeIsTheIntegralOfTheInverseCentrelineVelocity) {
  DownwashSettings dw;
  for (double thrust : {13.4, 40.0}) {  // uncapped and capped near the rotors
    const double s = 3.0;
    const int n = 200000;
    double t = 0.0;
    for (int k = 0; k < n; ++k)
      t += (s / n) / WakeCentrelineVelocity(dw, thrust, (k + 0.5) * s / n);
    EXPECT_NEAR(WakeTravelTime(dw, thrust, s), t, 1e-6) << thrust;
  }
}

TEST(WakeTest, HoveringVehicleGivesTheSteadyJetAndAMovingOneATrailingWake) {
  DownwashSettings dw;
  WakeTurbulenceSettings ts;
  WakeHistory h(dw, ts);
  const Vec3 up = Vec3::UnitZ();
  // Hovering at the origin for 2 s: the mean is the steady round jet.
  for (int k = 0; k <= 2000; ++k) h.Record(0.001 * k, Vec3::Zero(), up, 13.4);
  const Vec3 p(0.1, 0.0, -1.0);
  EXPECT_TRUE(h.MeanVelocity(2.0, p).isApprox(DownwashVelocity(dw, Vec3::Zero(), up, 13.4, p)));
  // Then it jumps 2 m sideways: 0.02 s later the air 2 m below the old position still comes
  // from the old position (travel time there ~0.45 s), and none has arrived below the new one.
  for (int k = 1; k <= 20; ++k) h.Record(2.0 + 0.001 * k, Vec3(2.0, 0.0, 0.0), up, 13.4);
  const Vec3 below_old(0.0, 0.0, -2.0), below_new(2.0, 0.0, -2.0);
  EXPECT_LT(h.MeanVelocity(2.02, below_old).z(), -2.0);
  EXPECT_NEAR(h.MeanVelocity(2.02, below_new).z(), 0.0, 1e-3);
  // After the travel time the wake has followed the vehicle.
  for (int k = 21; k <= 1500; ++k) h.Record(2.0 + 0.001 * k, Vec3(2.0, 0.0, 0.0), up, 13.4);
  EXPECT_LT(h.MeanVelocity(3.5, below_new).z(), -2.0);
  EXPECT_NEAR(h.MeanVelocity(3.5, below_old).z(), 0.0, 1e-3);
}

TEST(WakeTest, FluctuationsHaveTheRoundJetIntensitiesOnTheAxisAndAreSeeded) {
  // Constant local scales (U_c = 5 m/s, r_half = 0.4 m): on the axis the axial rms is 25 %
  // and each radial rms 20 % of U_c; the correlation time is 0.4 r_half / U_c.
  WakeTurbulenceSettings ts;
  WakeFluctuation a(ts, 3, 0, 1), b(ts, 3, 0, 1), c(ts, 4, 0, 1);
  const Vec3 axis = Vec3::UnitZ();
  const double uc = 5.0, hw = 0.4, dt = 0.001;
  const int n = 400000;
  double sa = 0.0, sr = 0.0, lag = 0.0;
  const int k_tau = static_cast<int>(std::lround(0.4 * hw / uc / dt));
  std::vector<double> axial(n);
  for (int k = 0; k < n; ++k) {
    a.Step(dt, uc, hw);
    b.Step(dt, uc, hw);
    c.Step(dt, uc, hw);
    const Vec3 v = a.Velocity(axis, uc, hw, 0.0);
    ASSERT_EQ(v, b.Velocity(axis, uc, hw, 0.0));
    axial[k] = v.z();
    sa += v.z() * v.z();
    sr += v.x() * v.x() + v.y() * v.y();
  }
  EXPECT_NE(a.state(), c.state());
  EXPECT_NEAR(std::sqrt(sa / n) / uc, 0.25, 0.01);
  EXPECT_NEAR(std::sqrt(sr / (2.0 * n)) / uc, 0.20, 0.008);
  for (int k = 0; k + k_tau < n; ++k) lag += axial[k] * axial[k + k_tau];
  EXPECT_NEAR(lag / (n - k_tau) / (sa / n), std::exp(-1.0), 0.05);
  // Off the axis the intensity falls: half at 1.6 half widths.
  EXPECT_NEAR(a.Velocity(axis, uc, hw, 1.6 * hw).norm() / a.Velocity(axis, uc, hw, 0.0).norm(), 0.5,
              1e-12);
}

}  // namespace
}  // namespace fnmpc::sim

namespace fnmpc::sim {
namespace {

TEST(WakeTest, VehicleBelowAnotherFeelsAFluctuatingDownwardPushWithLateralComponents) {
  // Given two hovering vehicles (rotors at the hover throttle), one 1 m below and 0.25 m
  // beside the other, both held in place, with the reality wake and rotor aerodynamics,
  WorldConfig c = test::QuietConfig(2);
  c.battery.fixed_voltage = true;
  c.downwash.enabled = true;
  c.reality.wake = true;
  c.reality.rotor_aerodynamics = true;
  const model::VehicleParams& p = c.vehicles[0].params;
  const double throttle = p.throttle.Throttle(p.mass * kGravity / 4.0, 16.8);
  c.vehicles[0].position = Vec3(0.0, 0.0, 3.0);
  c.vehicles[1].position = Vec3(0.25, 0.0, 2.0);
  for (auto& v : c.vehicles) v.initial_throttle = throttle;
  World w(c);
  // when the lower one's aerodynamic force is sampled for 5 s after the wake has arrived,
  std::vector<Vec3> f;
  for (int k = 0; k < 6000; ++k) {
    w.SetPose(0, Vec3(0.0, 0.0, 3.0), Vec3::Zero());
    w.SetPose(1, Vec3(0.25, 0.0, 2.0), Vec3::Zero());
    w.StepOnce();
    if (k >= 1000 && k % 5 == 0) f.push_back(w.GetTrueState(1).aero_force);
  }
  Vec3 mean = Vec3::Zero();
  for (const Vec3& x : f) mean += x / static_cast<double>(f.size());
  Vec3 var = Vec3::Zero();
  for (const Vec3& x : f) var += (x - mean).cwiseAbs2() / static_cast<double>(f.size());
  // then it is a downward push of several newtons (thrust lost in the inflow plus drag),
  EXPECT_LT(mean.z(), -2.0);
  // that fluctuates by at least 10 % of its mean,
  EXPECT_GE(std::sqrt(var.z()), 0.1 * std::abs(mean.z()));
  // with non-zero lateral components,
  EXPECT_GT(std::sqrt(var.x() + var.y()), 0.05);
  // while the upper vehicle feels nothing from the lower one's wake (only its own inflow).
  EXPECT_NEAR(w.GetTrueState(0).aero_force.x(), 0.0, 1e-9);
}

}  // namespace
}  // namespace fnmpc::sim

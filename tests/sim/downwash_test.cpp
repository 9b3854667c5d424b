// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/downwash.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "fnmpc/sim/world.hpp"
#include "sim_test_util.hpp"

namespace fnmpc::sim {
namespace {

/// Independent restatement of the documented jet model (docs/simulator.md): the speed of
/// the downward flow at downstream distance s and radial distance r under a vehicle with
/// thrust T.
double JetSpeed(const DownwashSettings& st, double thrust, double s, double r) {
  if (s <= 0.0 || thrust <= 0.0) return 0.0;
  const double half = st.wake_radius + st.spreading_rate * s;
  if (r > st.cutoff_half_widths * half) return 0.0;
  // Momentum flux of a Gaussian profile: rho U_c^2 pi half^2 / (2 ln 2) = T.
  double u_c = std::sqrt(2.0 * std::log(2.0) * thrust / (st.air_density * M_PI)) / half;
  const double area = 4.0 * M_PI * st.rotor_radius * st.rotor_radius;
  const double v_h = std::sqrt(thrust / (2.0 * st.air_density * area));
  u_c = std::min(u_c, st.exit_velocity_factor * v_h);
  return u_c * std::exp(-std::log(2.0) * (r / half) * (r / half));
}

TEST(DownwashTest, JetModelShape) {
  // Given the default settings and a hovering vehicle's thrust,
  const DownwashSettings st;
  const double thrust = 1.37 * kGravity;
  const Vec3 up(0, 0, 1);
  auto at = [&](double x, double z) {
    return DownwashVelocity(st, Vec3::Zero(), up, thrust, {x, 0, z});
  };
  // Then the flow points down along the axis, carries the momentum flux T
  const double v_h = HoverInducedVelocity(st, thrust);
  EXPECT_NEAR(v_h, std::sqrt(thrust / (2 * 1.225 * 4 * M_PI * 0.127 * 0.127)), 1e-12);
  EXPECT_EQ(at(0, -0.5).head<2>().norm(), 0.0);
  for (double s : {0.0, 1.0, 5.0}) {
    const double half = 0.3 + 0.094 * s;
    double flux = 0.0;  // rho * integral of U^2 2 pi r dr
    for (double r = 0.0005; r < 3.0 * half; r += 0.001) {
      flux += 1.225 * std::pow(at(r, -s - 1e-12).z(), 2) * 2.0 * M_PI * r * 0.001;
    }
    EXPECT_NEAR(flux, thrust, 1e-3 * thrust) << s;
  }
  // decays as 1 / (r0 + S s) along the centreline,
  EXPECT_NEAR(at(0, -8.0).z() / at(0, -4.0).z(), (0.3 + 0.094 * 4.0) / (0.3 + 0.094 * 8.0), 1e-12);
  EXPECT_LT(at(0, -0.5).z(), 0.0);
  EXPECT_GE(at(0, -0.5).z(), -2.0 * v_h);
  // is Gaussian in r (half the centreline speed at the half width r0 + S s),
  EXPECT_NEAR(at(0.3 + 0.094 * 6.0, -6.0).z() / at(0, -6.0).z(), 0.5, 1e-12);
  // is zero above the rotor plane and beyond the radial cut-off,
  EXPECT_EQ(at(0, 0.5).norm(), 0.0);
  EXPECT_EQ(at(3.0 * (0.3 + 0.094 * 6.0) + 0.01, -6.0).norm(), 0.0);
  // and follows a tilted thrust axis.
  const Vec3 axis = Vec3(0.3, 0.0, 1.0).normalized();
  const Vec3 v = DownwashVelocity(st, Vec3::Zero(), axis, thrust, -1.0 * axis);
  EXPECT_NEAR(v.normalized().dot(-axis), 1.0, 1e-12);
}

/// Aerodynamic force on a level lower vehicle at rest, `dz` below and `dx` beside an upper
/// vehicle at its hover throttle, measured in the World.
struct Pair {
  TrueState upper, lower;
};
Pair Measure(double dx, double dz) {
  WorldConfig c = test::QuietConfig(2);
  c.ground = false;
  c.downwash.enabled = true;
  c.battery.fixed_voltage = true;
  const model::VehicleParams& p = c.vehicles[0].params;
  c.vehicles[0].initial_throttle = p.throttle.Throttle(p.mass * kGravity / 4.0, 16.8);
  c.vehicles[0].position = Vec3(0, 0, 20);
  c.vehicles[1].position = Vec3(dx, 0, 20 - dz);
  World world(c);
  for (int k = 0; k < 3; ++k) {
    world.SetPose(0, Vec3(0, 0, 20), Vec3::Zero());
    world.SetPose(1, Vec3(dx, 0, 20 - dz), Vec3::Zero());
    world.StepOnce();
  }
  return {world.GetTrueState(0), world.GetTrueState(1)};
}

/// Expected force from the independent model: quadratic drag c/4 at each rotor point.
double ExpectedFz(const Pair& pr, double dx, double dz) {
  const DownwashSettings st;
  const WorldConfig c;
  const double a = 0.225 / std::sqrt(2.0);
  double fz = 0.0;
  for (double rx : {a, -a}) {
    for (double ry : {a, -a}) {
      const double u = JetSpeed(st, pr.upper.thrust, dz, std::hypot(dx + rx, ry));
      fz -= 0.25 * c.drag_coefficient.z() * u * u;
    }
  }
  return fz;
}

TEST(DownwashTest, ForceOnLowerVehicleInWorld) {
  double previous = kInf;
  for (double dz : {0.5, 1.0, 2.0, 4.0, 8.0}) {
    // Given a vehicle hovering dz above another,
    const Pair pr = Measure(0.0, dz);
    // Then the lower one is pushed down by the modelled amount, with no side force,
    const double fz = pr.lower.aero_force.z();
    EXPECT_LT(fz, 0.0) << dz;
    EXPECT_NEAR(fz, ExpectedFz(pr, 0.0, dz), 1e-9 + 1e-9 * std::abs(fz)) << dz;
    EXPECT_LT(pr.lower.aero_force.head<2>().norm(), 1e-9 * std::abs(fz));
    // and the push does not grow with distance (it decays beyond the jet core);
    EXPECT_LT(std::abs(fz), 0.9 * previous) << dz;
    previous = std::abs(fz);
    // the upper vehicle feels nothing.
    EXPECT_EQ(pr.upper.aero_force.norm(), 0.0);
  }
  // A vehicle 1 m below loses a noticeable share (> 5 %) of its weight.
  EXPECT_GT(std::abs(Measure(0.0, 1.0).lower.aero_force.z()), 0.05 * 1.37 * kGravity);
}

TEST(DownwashTest, OffsetGivesTorqueAndSideBySideGivesNothing) {
  // Given the lower vehicle 1 m below and 0.3 m ahead of the jet axis,
  const Pair off = Measure(0.3, 1.0);
  // Then its rear rotors (nearer the axis) are pushed harder: a nose-up pitch torque.
  EXPECT_LT(off.lower.aero_force.z(), 0.0);
  EXPECT_NEAR(off.lower.aero_force.z(), ExpectedFz(off, 0.3, 1.0), 1e-9);
  EXPECT_LT(off.lower.aero_torque.y(), -1e-3);
  // Given two vehicles side by side 3 m apart, Then neither feels any downwash.
  const Pair side = Measure(3.0, 0.0);
  EXPECT_EQ(side.lower.aero_force.norm(), 0.0);
  EXPECT_EQ(side.lower.aero_torque.norm(), 0.0);
  // Given the lower one far out to the side (> 3 half widths), Then the Gaussian profile is cut
  // off.
  EXPECT_EQ(Measure(3.0, 1.0).lower.aero_force.norm(), 0.0);
  EXPECT_GT(std::abs(Measure(0.8, 1.0).lower.aero_force.z()), 0.0);
}

TEST(DownwashTest, WindDragFollowsQuadraticLaw) {
  // Given a level vehicle at rest in a 3 m/s wind along x,
  WorldConfig c = test::QuietConfig(1);
  c.ground = false;
  c.wind.enabled = true;
  c.wind.velocity = Vec3(3.0, 0.0, 0.0);
  c.vehicles[0].position = Vec3(0, 0, 10);
  World world(c);
  world.StepOnce();
  // Then the drag is c_x v |v| along the wind.
  const TrueState s = world.GetTrueState(0);
  EXPECT_NEAR(s.aero_force.x(), c.drag_coefficient.x() * 9.0, 1e-9);
  EXPECT_NEAR(s.aero_force.tail<2>().norm(), 0.0, 1e-9);
  // When 2 s pass, Then the vehicle drifts downwind.
  world.Step(2.0);
  EXPECT_GT(world.GetTrueState(0).position.x(), 0.05);
}

TEST(DownwashTest, BadSettingsRejected) {
  DownwashSettings st;
  st.rotor_radius = 0.0;
  EXPECT_THROW(st.Validate(), std::invalid_argument);
  WorldConfig c = test::QuietConfig(1);
  c.wind.gust_time_constant = 0.0;
  EXPECT_THROW(World w(c), std::invalid_argument);
}

}  // namespace
}  // namespace fnmpc::sim

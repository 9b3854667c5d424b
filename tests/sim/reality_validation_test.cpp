// SPDX-License-Identifier: BSD-3-Clause
// The reality models against published measurements (docs/simulator.md "Validation against
// published measurements"): a propeller's thrust in axial inflow (UIUC propeller database), the
// far-field decay of the wake (round turbulent jet measurements), the wake below a hovering
// quadrotor (the far-field fit of Bauersfeld et al. 2024, as transcribed by a third party) and
// the force on a vehicle hovering below another (Neural-Swarm's Crazyflie measurements, as read
// off the figure by a third party). Nothing here is fitted: the models run with the simulator's
// defaults; the tolerances are stated with the comparison, misses included.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "fnmpc/config/csv_reader.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/sim/downwash.hpp"
#include "fnmpc/sim/rotor_aero.hpp"
#include "fnmpc/sim/wake.hpp"
#include "fnmpc/sim/world.hpp"
#include "tools/reality_validation_scene.hpp"

namespace fnmpc::sim {
namespace {

struct Point {
  double x, y;
};

/// The (J, C_T) rows of a reference table in tests/sim/data (the project's CSV reader; the
/// source is quoted in '#' lines above the header).
std::vector<Point> ReadTable(const std::string& name) {
  const config::CsvTable t =
      config::ReadCsv(std::string(FNMPC_SOURCE_DIR) + "/tests/sim/data/" + name, {"J", "CT"}, "J",
                      /*hash_comments=*/true);
  std::vector<Point> out;
  for (std::size_t r = 0; r < t.rows(); ++r) out.push_back({t.Column("J")[r], t.Column("CT")[r]});
  return out;
}

/// UIUC thrust coefficient C_T = T / (rho n^2 D^4) of the simulator's axial-inflow model for a
/// rotor at n [rev/s] whose static thrust is `static_thrust` [N], at advance ratio J.
double ModelCt(const RotorBlade& b, double static_thrust, double n, double j) {
  const double d = 2.0 * b.radius;
  const double omega = 2.0 * M_PI * n;
  const double t = static_thrust * AxialInflowThrustRatio(b, static_thrust, omega, j * n * d);
  return t / (b.air_density * n * n * d * d * d * d);
}

TEST(RealityValidationTest, PropellerThrustInAxialInflowAgainstUiucApc10x7) {
  // Given the UIUC wind-tunnel data of an APC 10x7 (10-inch, as the simulator's default blade)
  // at 4011 RPM, and the simulator's rotor model with its default solidity and lift slope,
  const std::vector<Point> data = ReadTable("uiuc_apc10x7_4011rpm.csv");
  ASSERT_EQ(data.size(), 17u);
  const RotorBlade b;
  const double n = 4011.0 / 60.0;
  // whose effective pitch is set the way the simulator sets it, from one measured thrust (the
  // simulator uses the static one; the table starts at J = 0.144, so its first point is used):
  const double d = 2.0 * b.radius;
  const double t_first = data[0].y * b.air_density * n * n * d * d * d * d;
  double lo = t_first;
  double hi = 10.0 * t_first;
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (ModelCt(b, mid, n, data[0].x) < data[0].y ? lo : hi) = mid;
  }
  const double t_static = 0.5 * (lo + hi);
  ASSERT_NEAR(ModelCt(b, t_static, n, data[0].x), data[0].y, 1e-9);
  // Then the predicted C_T follows the measured one within 4 % of the first point's C_T up to
  // J = 0.40 (axial inflow up to 10 m/s at the shipped vehicle's hover rotor speed, the range
  // a formation flight sees), and within 15 % up to the table's end (J = 0.72), where the
  // uniform-pitch, drag-free blade model loses thrust faster than the twisted propeller (miss
  // of 13 % at J = 0.72, reported in docs/simulator.md).
  double worst_low = 0.0;
  double worst_all = 0.0;
  for (const Point& p : data) {
    const double err = (ModelCt(b, t_static, n, p.x) - p.y) / data[0].y;
    if (p.x <= 0.40) worst_low = std::max(worst_low, std::abs(err));
    worst_all = std::max(worst_all, std::abs(err));
    std::printf("J %.3f  C_T UIUC %.4f  model %.4f  error %+.1f %% of C_T(0.144)\n", p.x, p.y,
                ModelCt(b, t_static, n, p.x), 100.0 * err);
  }
  EXPECT_LE(worst_low, 0.04);
  EXPECT_LE(worst_all, 0.15);
  // and the thrust falls with the inflow as measured (the slope over J = 0.144..0.251 within
  // 25 %: measured -0.150, the sign and size of what the follower in a wake feels).
  const double slope_data = (data[3].y - data[0].y) / (data[3].x - data[0].x);
  const double slope_model =
      (ModelCt(b, t_static, n, data[3].x) - ModelCt(b, t_static, n, data[0].x)) /
      (data[3].x - data[0].x);
  EXPECT_NEAR(slope_model / slope_data, 1.0, 0.25) << slope_model << " vs " << slope_data;
}

TEST(RealityValidationTest, WakeCentrelineDecayAgainstRoundJetMeasurements) {
  // Given the self-similar round jet as measured by Hussein, Capp and George (1994, J. Fluid
  // Mech. 258, laser-Doppler; tabulated in Pope 2000, Turbulent Flows, Table 5.1): centreline
  // velocity U_c = B d U_J / (x - x_0) with B = 5.8, where a jet of momentum flux T has
  // d U_J = sqrt(4 T / (pi rho)),
  const double b_measured = 5.8;
  const DownwashSettings dw;
  for (double thrust : {13.4, 20.0, 30.0}) {
    const double d_uj = std::sqrt(4.0 * thrust / (M_PI * dw.air_density));
    // Then far below the vehicle (10 to 40 m, where the simulator's jet is self-similar) its
    // centreline velocity times the distance from its virtual origin, U_c (s + r_0 / S),
    // equals B d U_J within 10 % (the Gaussian profile's momentum balance gives 8 % more).
    for (double s : {10.0, 20.0, 40.0}) {
      const double product =
          WakeCentrelineVelocity(dw, thrust, s) * (s + dw.wake_radius / dw.spreading_rate);
      EXPECT_NEAR(product / (b_measured * d_uj), 1.0, 0.10) << thrust << " N, s " << s;
    }
  }
}

/// Far-field fit of the mean velocity below hovering quadrotors of Bauersfeld, Muller, Ziegler,
/// Coletti and Scaramuzza (IEEE RA-L 2024, arXiv 2403.13321), in their normalisation: lengths
/// over the distance between opposite motors l, velocities over U_H = sqrt(m g / (2 rho 4 pi
/// R^2)) (the simulator's v_h). Constants and equations as transcribed, with the paper's
/// equation numbers, in github.com/learnsyslab/crazyflow examples/plugins/downwash.py (commit
/// 4b32a459608c2de120dcb86fea941ee572dbf129): Eq. (9) B_d = 10.11, S = 0.07668, s_0 = -5.817;
/// Eq. (2) U_c / U_H = B_d / (s/l - s_0); Eq. (6) r_1/2 / l = S (s/l - s_0); Eq. (3)
/// U = U_c / (1 + (sqrt2 - 1) xi^2)^2 with xi = r / r_1/2. The paper itself could not be read
/// from the development machine (docs/simulator.md says what was searched).
struct QuadrotorJetFit {
  double bd = 10.11;
  double spreading = 0.07668;
  double s0 = -5.817;
  [[nodiscard]] double Centreline(double s_l) const { return bd / (s_l - s0); }
  [[nodiscard]] double HalfWidth(double s_l) const { return spreading * (s_l - s0); }
  [[nodiscard]] double Velocity(double s_l, double r_l) const {
    const double xi = r_l / HalfWidth(s_l);
    const double d = 1.0 + (std::sqrt(2.0) - 1.0) * xi * xi;
    return Centreline(s_l) / (d * d);
  }
};

model::VehicleParams ShippedVehicle() {
  return config::LoadVehicleFile(std::string(FNMPC_SOURCE_DIR) +
                                 "/config/vehicles/storm-drone-4.yaml");
}

TEST(RealityValidationTest, WakeBelowHoveringQuadrotorAgainstBauersfeldFarFieldFit) {
  // Given the shipped vehicle hovering (l = 2 arm_length = 0.45 m between opposite motors) and
  // the quadrotor far-field fit, in the fit's range (jet-like from 2.5 vehicle sizes down),
  const model::VehicleParams p = ShippedVehicle();
  const double l = 2.0 * p.arm_length;
  const double thrust = p.mass * kGravity;
  const DownwashSettings dw;
  const double u_h = HoverInducedVelocity(dw, thrust);
  const QuadrotorJetFit fit;
  for (double s_l : {2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0}) {
    const double s = s_l * l;
    const auto sim_u = [&](double r_l) {
      return -DownwashVelocity(dw, Vec3::Zero(), Vec3::UnitZ(), thrust, Vec3(r_l * l, 0.0, -s))
                  .z() /
             u_h;
    };
    // Then on the axis the simulator's velocity is within 15 % of the fit (it is 9-14 % lower),
    const double centre = WakeCentrelineVelocity(dw, thrust, s) / u_h / fit.Centreline(s_l);
    EXPECT_NEAR(centre, 1.0, 0.15) << "s/l " << s_l;
    EXPECT_NEAR(sim_u(0.0), WakeCentrelineVelocity(dw, thrust, s) / u_h, 1e-9);
    // where the rotors of a vehicle of the same size directly below sit (r = l/2) it is within
    // 10 % (2-9 % higher),
    EXPECT_NEAR(sim_u(0.5) / fit.Velocity(s_l, 0.5), 1.0, 0.10) << "s/l " << s_l;
    // and its half width is 1.3-1.4 times the fit's: a miss, the simulator's jet is wider and
    // carries the whole rotor thrust as momentum flux (documented in docs/simulator.md).
    const double width = WakeHalfWidth(dw, s) / l / fit.HalfWidth(s_l);
    EXPECT_GT(width, 1.25) << "s/l " << s_l;
    EXPECT_LT(width, 1.45) << "s/l " << s_l;
    std::printf(
        "s/l %4.1f  U_c/U_H sim %.3f fit %.3f  U(l/2)/U_H sim %.3f fit %.3f  r_1/2/l "
        "sim %.3f fit %.3f\n",
        s_l, WakeCentrelineVelocity(dw, thrust, s) / u_h, fit.Centreline(s_l), sim_u(0.5),
        fit.Velocity(s_l, 0.5), WakeHalfWidth(dw, s) / l, fit.HalfWidth(s_l));
  }
}

/// Mean downward aerodynamic force [N] on the shipped vehicle held `dz` [m] directly below
/// another, both at the hover throttle, reality on (rotor inflow, advected turbulent wake):
/// averaged over 4 s after a 2 s wake build-up.
double MeanDownwardForceBelow(const model::VehicleParams& p, double dz) {
  const std::vector<Vec3> f = validation::ForceBelowHoveringVehicle(p, dz, true, 6000, 2000, 1);
  double sum = 0.0;
  int n = 0;
  for (const Vec3& x : f) {
    sum -= x.z();
    ++n;
  }
  return sum / n;
}

TEST(RealityValidationTest, ForceBelowHoveringVehicleAgainstNeuralSwarmCrazyflies) {
  // Given the Neural-Swarm measurement of two hovering Crazyflies (34 g), the lower directly
  // below the upper (Fig. 3 of Shi et al. 2020 as read off by a third party, see the data
  // file), compared in normalised form: the force as a share of the weight, which is the upper
  // vehicle's thrust for identical vehicles in hover, against the vertical distance over the
  // distance between opposite motors l (the length scale under which Bauersfeld et al. find
  // the wakes of differently sized quadrotors alike, velocities scaling with the hover induced
  // velocity; disk loadings and Reynolds numbers of the two vehicles are not matched),
  const config::CsvTable cf = config::ReadCsv(
      std::string(FNMPC_SOURCE_DIR) + "/tests/sim/data/neural_swarm_fig3_crazyflie.csv",
      {"separation_m", "force_g", "weight_g", "motor_distance_m"}, "separation_m",
      /*hash_comments=*/true);
  ASSERT_EQ(cf.rows(), 4u);
  const model::VehicleParams p = ShippedVehicle();
  const double l = 2.0 * p.arm_length;
  double previous_sim = 1e9;
  for (std::size_t r = 0; r < cf.rows(); ++r) {
    const double s_l = cf.Column("separation_m")[r] / cf.Column("motor_distance_m")[r];
    const double measured = cf.Column("force_g")[r] / cf.Column("weight_g")[r];
    // When the shipped vehicle hovers at the same s/l below another,
    const double simulated = MeanDownwardForceBelow(p, s_l * l) / (p.mass * kGravity);
    std::printf("s/l %.2f  force/weight measured %.3f simulated %.3f  ratio %.2f\n", s_l, measured,
                simulated, simulated / measured);
    // Then the simulated push falls with the distance as the measured one does,
    EXPECT_LT(simulated, previous_sim);
    previous_sim = simulated;
    // but is 1.5-3.5 times the measured share: a miss of the model (too strong, and falling too
    // slowly with distance), stated in docs/simulator.md and reported, not tuned away.
    EXPECT_GT(simulated / measured, 1.5) << "s/l " << s_l;
    EXPECT_LT(simulated / measured, 3.5) << "s/l " << s_l;
  }
}

}  // namespace
}  // namespace fnmpc::sim

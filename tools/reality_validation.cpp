// SPDX-License-Identifier: BSD-3-Clause
// Model side of the validation plots of docs/simulator.md ("Validation against published
// measurements"), printed as CSV blocks for tools/reality_validation.py:
//   [propeller]  the simulator's axial-inflow thrust model for the UIUC APC 10x7 at 4011 RPM,
//                its effective pitch set from the table's first point (as the unit test does);
//   [wake]       the mean wake velocity below the shipped vehicle hovering (13.4 N);
//   [force]      the aerodynamic force on the shipped vehicle hovering 2-6 rotor diameters
//                directly below another, both held in place in the World, reality on (rotor
//                inflow, advected turbulent wake: mean and standard deviation over 10 s) and
//                off (steady jet acting as body drag);
//   [quadrotor_wake], [quadrotor_profiles]  the same mean wake in the normalisation of
//                Bauersfeld et al. (2024): U / U_H against s / l and r / l, l the distance
//                between opposite motors (2 arm_length of the vehicle file);
//   [force_per_weight]  the force of [force] as a share of the weight (= the upper vehicle's
//                thrust) at vertical distances s / l, reality on, for the Crazyflie comparison.
// Usage: reality_validation UIUC_CSV CRAZYFLIE_CSV
//   (tests/sim/data/uiuc_apc10x7_4011rpm.csv, tests/sim/data/neural_swarm_fig3_crazyflie.csv)
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "fnmpc/config/csv_reader.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/sim/downwash.hpp"
#include "fnmpc/sim/rotor_aero.hpp"
#include "fnmpc/sim/wake.hpp"
#include "fnmpc/sim/world.hpp"
#include "tools/reality_validation_scene.hpp"

namespace {

using fnmpc::Vec3;
namespace sim = fnmpc::sim;

double ModelCt(const sim::RotorBlade& b, double static_thrust, double n, double j) {
  const double d = 2.0 * b.radius;
  const double t =
      static_thrust * sim::AxialInflowThrustRatio(b, static_thrust, 2.0 * M_PI * n, j * n * d);
  return t / (b.air_density * n * n * d * d * d * d);
}

void Propeller(double j0, double ct0) {
  const sim::RotorBlade b;
  const double n = 4011.0 / 60.0;
  const double d = 2.0 * b.radius;
  const double t_first = ct0 * b.air_density * n * n * d * d * d * d;
  double lo = t_first, hi = 10.0 * t_first;
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (ModelCt(b, mid, n, j0) < ct0 ? lo : hi) = mid;
  }
  std::printf("[propeller]\nJ,ct_model\n");
  for (int k = 0; k <= 80; ++k) std::printf("%.3f,%.5f\n", 0.01 * k, ModelCt(b, lo, n, 0.01 * k));
}

void Wake(double thrust) {
  const sim::DownwashSettings dw;
  const double diameter = 2.0 * dw.rotor_radius;
  const double v_h = sim::HoverInducedVelocity(dw, thrust);
  std::printf("[wake]\nthrust,v_h,rotor_diameter\n%.4f,%.5f,%.4f\n", thrust, v_h, diameter);
  std::printf("s_over_D,r_over_D,u_over_vh\n");
  for (double s_d : {2.0, 4.0, 6.0, 8.0, 12.0}) {
    for (int k = 0; k <= 60; ++k) {
      const double r_d = 0.1 * k;
      const Vec3 v = sim::DownwashVelocity(dw, Vec3::Zero(), Vec3::UnitZ(), thrust,
                                           Vec3(r_d * diameter, 0.0, -s_d * diameter));
      std::printf("%.1f,%.2f,%.5f\n", s_d, r_d, -v.z() / v_h);
    }
  }
  std::printf("[centreline]\ns_over_D,uc_over_vh\n");
  for (int k = 1; k <= 200; ++k) {
    const double s_d = 0.1 * k;
    std::printf("%.1f,%.5f\n", s_d, sim::WakeCentrelineVelocity(dw, thrust, s_d * diameter) / v_h);
  }
}

struct ForceStats {
  Vec3 mean = Vec3::Zero();
  Vec3 sd = Vec3::Zero();
};

ForceStats ForceBelow(const fnmpc::model::VehicleParams& p, double dz, bool reality) {
  const std::vector<Vec3> f =
      fnmpc::validation::ForceBelowHoveringVehicle(p, dz, reality, 12000, 2000, 5);
  ForceStats st;
  for (const Vec3& x : f) st.mean += x / static_cast<double>(f.size());
  for (const Vec3& x : f) st.sd += (x - st.mean).cwiseAbs2() / static_cast<double>(f.size());
  st.sd = st.sd.cwiseSqrt();
  return st;
}

// The mean wake of the shipped vehicle hovering (thrust [N]), in the variables of Bauersfeld et
// al. (2024): U_H = sqrt(T / (2 rho 4 pi R^2)) (the simulator's v_h), lengths over the
// distance between opposite motors l [m].
void QuadrotorWake(double thrust, double l) {
  const sim::DownwashSettings dw;
  const double u_h = sim::HoverInducedVelocity(dw, thrust);
  std::printf("[quadrotor_wake]\nthrust,u_h,motor_distance\n%.4f,%.5f,%.4f\n", thrust, u_h, l);
  std::printf("s_over_l,uc_over_uh,half_width_over_l\n");
  for (int k = 5; k <= 200; ++k) {
    const double s = 0.1 * k * l;
    std::printf("%.1f,%.5f,%.5f\n", 0.1 * k, sim::WakeCentrelineVelocity(dw, thrust, s) / u_h,
                sim::WakeHalfWidth(dw, s) / l);
  }
  std::printf("[quadrotor_profiles]\ns_over_l,r_over_l,u_over_uh\n");
  for (double s_l : {2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 20.0}) {
    for (int k = 0; k <= 100; ++k) {
      const double r_l = 0.02 * k;
      const Vec3 v = sim::DownwashVelocity(dw, Vec3::Zero(), Vec3::UnitZ(), thrust,
                                           Vec3(r_l * l, 0.0, -s_l * l));
      std::printf("%.1f,%.2f,%.5f\n", s_l, r_l, -v.z() / u_h);
    }
  }
}

// The downward aerodynamic force on the lower vehicle (reality on) over its weight at vertical
// distances s / l: a grid over 2-6 and the distances of the Crazyflie data.
void ForcePerWeight(const fnmpc::model::VehicleParams& p, const std::vector<double>& data_s_l) {
  const double l = 2.0 * p.arm_length;
  std::vector<double> s_l = data_s_l;
  for (int k = 0; k <= 16; ++k) s_l.push_back(2.0 + 0.25 * k);
  std::printf("[force_per_weight]\ns_over_l,fz_over_weight,fz_sd_over_weight\n");
  for (double x : s_l) {
    const ForceStats on = ForceBelow(p, x * l, true);
    const double w = p.mass * fnmpc::kGravity;
    std::printf("%.4f,%.5f,%.5f\n", x, -on.mean.z() / w, on.sd.z() / w);
  }
}

void Force(const fnmpc::model::VehicleParams& p) {
  const double diameter = 2.0 * sim::DownwashSettings().rotor_radius;
  std::printf("[force]\nseparation_D,fz_on_mean,fz_on_sd,fxy_on_sd,fz_off,weight\n");
  for (double sep = 2.0; sep <= 6.01; sep += 0.5) {
    const ForceStats on = ForceBelow(p, sep * diameter, true);
    const ForceStats off = ForceBelow(p, sep * diameter, false);
    std::printf("%.1f,%.4f,%.4f,%.4f,%.4f,%.4f\n", sep, on.mean.z(), on.sd.z(),
                std::hypot(on.sd.x(), on.sd.y()), off.mean.z(), p.mass * fnmpc::kGravity);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s UIUC_CSV CRAZYFLIE_CSV\n", argv[0]);
    return 2;
  }
  try {
    // The UIUC table's first point (J, C_T); its source is quoted in '#' lines.
    const fnmpc::config::CsvTable uiuc =
        fnmpc::config::ReadCsv(argv[1], {"J", "CT"}, "J", /*hash_comments=*/true);
    const double j0 = uiuc.Column("J")[0], ct0 = uiuc.Column("CT")[0];
    const fnmpc::model::VehicleParams p = fnmpc::config::LoadVehicleFile(
        std::string(FNMPC_SOURCE_DIR) + "/config/vehicles/storm-drone-4.yaml");
    Propeller(j0, ct0);
    Wake(p.mass * fnmpc::kGravity);
    Force(p);
    QuadrotorWake(p.mass * fnmpc::kGravity, 2.0 * p.arm_length);
    // The Crazyflie data's vertical distances over the Crazyflie's distance between opposite
    // motors (its '#' lines give the source of both).
    const fnmpc::config::CsvTable cf = fnmpc::config::ReadCsv(
        argv[2], {"separation_m", "force_g", "weight_g", "motor_distance_m"}, "separation_m",
        /*hash_comments=*/true);
    std::vector<double> s_l;
    for (std::size_t r = 0; r < cf.rows(); ++r) {
      s_l.push_back(cf.Column("separation_m")[r] / cf.Column("motor_distance_m")[r]);
    }
    ForcePerWeight(p, s_l);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}

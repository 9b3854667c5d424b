// SPDX-License-Identifier: BSD-3-Clause
// The reality models against published measurements (docs/simulator.md "Validation against
// published measurements"): a propeller's thrust in axial inflow (UIUC propeller database) and
// the far-field decay of the wake (round turbulent jet measurements). Nothing here is fitted:
// the models run with the simulator's defaults; the tolerances are stated with the comparison.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "fnmpc/config/csv_reader.hpp"
#include "fnmpc/sim/downwash.hpp"
#include "fnmpc/sim/rotor_aero.hpp"
#include "fnmpc/sim/wake.hpp"

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

}  // namespace
}  // namespace fnmpc::sim

// SPDX-License-Identifier: BSD-3-Clause
// End to end: `fnmpc sysid synth` writes a campaign made with the simulator from a vehicle
// that differs from the shipped one, `fnmpc sysid` identifies it and `fnmpc calibrate`
// recovers the injected biases; all compared with the synthesiser's truth.yaml.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <unistd.h>

#include "fnmpc/config/vehicle_yaml.hpp"

namespace fnmpc {
namespace {

namespace fs = std::filesystem;

int RunApp(const std::string& args, const fs::path& log) {
  const std::string cmd = std::string(FNMPC_APP) + " " + args + " > '" + log.string() + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  std::printf("$ fnmpc %s\n%s", args.c_str(), ss.str().c_str());
  return rc;
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class RoundTripTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // One directory per process: ctest runs each test of this suite as its own process,
    // in parallel, and each runs the whole pipeline in SetUpTestSuite.
    dir_ = fs::path(::testing::TempDir()) / ("fnmpc_sysid_roundtrip_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "out");
    synth_rc_ = RunApp("sysid synth '" + (dir_ / "c").string() + "'", dir_ / "synth.log");
    sysid_rc_ = RunApp("sysid '" + (dir_ / "c" / "campaign.yaml").string() + "' -o '" +
                           (dir_ / "out" / "vehicle.yaml").string() + "' --no-plots",
                       dir_ / "sysid.log");
    calib_rc_ = RunApp("calibrate '" + (dir_ / "out" / "vehicle.yaml").string() + "' '" +
                           (dir_ / "c" / "flight.csv").string() + "' -o '" +
                           (dir_ / "out" / "calibrated.yaml").string() + "' --no-plots",
                       dir_ / "calibrate.log");
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static inline fs::path dir_;
  static inline int synth_rc_ = -1, sysid_rc_ = -1, calib_rc_ = -1;
};

TEST_F(RoundTripTest, IdentifiesTheSynthesisedVehicle) {
  // Given a synthetic campaign and its truth, When identified,
  ASSERT_EQ(synth_rc_, 0);
  ASSERT_EQ(sysid_rc_, 0);
  const auto truth = config::LoadVehicleFile((dir_ / "c" / "truth.yaml").string());
  const auto id = config::LoadVehicleFile((dir_ / "out" / "vehicle.yaml").string());
  // Then mass is exact, inertia within 5 %, constants within 3 %, tau within 8 %,
  // gains within 3 %, throttle within 0.02 over 2-8 N and 15-16.8 V,
  EXPECT_EQ(id.mass, truth.mass);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(id.inertia[a], truth.inertia[a], 0.05 * truth.inertia[a]) << a;
    EXPECT_NEAR(id.attitude_time_constant[a], truth.attitude_time_constant[a],
                0.08 * truth.attitude_time_constant[a])
        << a;
    EXPECT_NEAR(id.attitude_gain[a], truth.attitude_gain[a], 0.03 * truth.attitude_gain[a]) << a;
    // The PD gains are checked loosely (no tolerance is specified for them).
    EXPECT_NEAR(id.attitude_kp[a], truth.attitude_kp[a], 0.15 * truth.attitude_kp[a]) << a;
    EXPECT_NEAR(id.attitude_kd[a], truth.attitude_kd[a], 0.15 * truth.attitude_kd[a]) << a;
  }
  EXPECT_NEAR(id.thrust_constant, truth.thrust_constant, 0.03 * truth.thrust_constant);
  EXPECT_NEAR(id.torque_constant, truth.torque_constant, 0.03 * truth.torque_constant);
  double worst = 0.0;
  for (double f = 2.0; f <= 8.0; f += 0.25) {
    for (double v = 15.0; v <= 16.8; v += 0.1) {
      worst = std::max(worst, std::abs(id.throttle.Throttle(f, v) - truth.throttle.Throttle(f, v)));
    }
  }
  EXPECT_LT(worst, 0.02);
  EXPECT_EQ(id.arm_length, truth.arm_length);
  EXPECT_FALSE(id.has_bias);
  // and the report directory holds the CSV dumps (plots when matplotlib is there).
  const fs::path rep = dir_ / "out" / "vehicle.yaml.report";
  EXPECT_TRUE(fs::exists(rep / "summary.json"));
  EXPECT_TRUE(fs::exists(rep / "attitude_roll.csv"));
  EXPECT_FALSE(fs::exists(dir_ / "out" / "vehicle.yaml.report.tmp"));
  // (The fixture runs without plots, which take seconds; the script is run here once.)
  if (std::system("/usr/bin/python3 -c 'import matplotlib' > /dev/null 2>&1") == 0) {
    const std::string script = std::string(FNMPC_SOURCE_DIR) + "/tools/sysid_report.py";
    const std::string cmd =
        "MPLBACKEND=Agg /usr/bin/python3 '" + script + "' '" + rep.string() + "'";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    EXPECT_TRUE(fs::exists(rep / "summary.md"));
    EXPECT_TRUE(fs::exists(rep / "attitude_roll.png"));
    EXPECT_TRUE(fs::exists(rep / "pendulum_x.png"));
    EXPECT_TRUE(fs::exists(rep / "bench.png"));
  }
}

TEST_F(RoundTripTest, CalibrationRecoversInjectedBiases) {
  // Given the identified vehicle and the synthetic flight of the biased truth,
  ASSERT_EQ(calib_rc_, 0);
  const auto truth = config::LoadVehicleFile((dir_ / "c" / "truth.yaml").string());
  const auto cal = config::LoadVehicleFile((dir_ / "out" / "calibrated.yaml").string());
  // When calibrated, Then roll/pitch biases are within 0.3 deg and the thrust scale within 1 %.
  const double deg = M_PI / 180.0;
  ASSERT_TRUE(cal.has_bias);
  EXPECT_NEAR(cal.bias.roll, truth.bias.roll, 0.3 * deg);
  EXPECT_NEAR(cal.bias.pitch, truth.bias.pitch, 0.3 * deg);
  EXPECT_NEAR(cal.bias.thrust_scale, truth.bias.thrust_scale, 0.01 * truth.bias.thrust_scale);
  const std::string log = Slurp(dir_ / "calibrate.log");
  EXPECT_NE(log.find("before"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir_ / "out" / "calibrated.yaml.report" / "windows.csv"));
}

TEST_F(RoundTripTest, BadFileNamesPositionAndWritesNothing) {
  // Given the campaign with a non-numeric cell in bench.csv line 5, thrust column,
  ASSERT_EQ(synth_rc_, 0);
  const fs::path bad = dir_ / "bad";
  fs::remove_all(bad);
  fs::copy(dir_ / "c", bad);
  std::ifstream in(bad / "bench.csv");
  std::string line, text;
  for (int n = 1; std::getline(in, line); ++n) {
    if (n == 5) line = "0.36,15.0,4000,oops,0.02";
    text += line + "\n";
  }
  in.close();
  std::ofstream(bad / "bench.csv") << text;
  // When identified,
  const fs::path out = bad / "vehicle.yaml";
  const int rc = RunApp(
      "sysid '" + (bad / "campaign.yaml").string() + "' -o '" + out.string() + "' --no-plots",
      bad / "sysid.log");
  // Then it fails naming file, line and column, and writes no output.
  EXPECT_NE(rc, 0);
  EXPECT_NE(Slurp(bad / "sysid.log").find("bench.csv:5:16: column 'thrust': not a number"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(bad / "vehicle.yaml.report"));
  // And a calibration with a flight whose time goes backwards fails the same way.
  std::ifstream fin(bad / "flight.csv");
  text.clear();
  for (int n = 1; std::getline(fin, line); ++n) {
    if (n == 4) line = "0" + line.substr(line.find(','));
    text += line + "\n";
  }
  fin.close();
  std::ofstream(bad / "flight.csv") << text;
  const int rc2 = RunApp("calibrate '" + (dir_ / "out" / "vehicle.yaml").string() + "' '" +
                             (bad / "flight.csv").string() + "' -o '" +
                             (bad / "cal.yaml").string() + "' --no-plots",
                         bad / "calibrate.log");
  EXPECT_NE(rc2, 0);
  EXPECT_NE(Slurp(bad / "calibrate.log").find("flight.csv:4:1: column 't'"), std::string::npos);
  EXPECT_FALSE(fs::exists(bad / "cal.yaml"));
}

}  // namespace
}  // namespace fnmpc

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
#include <functional>
#include <sstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

#include "fnmpc/config/vehicle_yaml.hpp"

namespace fnmpc {
namespace {

namespace fs = std::filesystem;

// Runs fnmpc with `args` (shell words), output to `log`; `timeout_s` > 0 bounds its run time
// (exit status 124 when it was killed).
int RunApp(const std::string& args, const fs::path& log, int timeout_s = 0) {
  const std::string prefix = timeout_s > 0 ? "timeout " + std::to_string(timeout_s) + " " : "";
  const std::string cmd =
      prefix + std::string(FNMPC_APP) + " " + args + " > '" + log.string() + "' 2>&1";
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

// Copies the synthetic campaign to `name` and replaces line `line_no` (1-based) of `file`
// by `replacement` (the line's cells as `edit` returns them).
fs::path CopyCampaign(const fs::path& from, const fs::path& to) {
  fs::remove_all(to);
  fs::copy(from, to);
  return to;
}

void EditLine(const fs::path& file, int line_no,
              const std::function<std::string(std::string)>& edit) {
  std::ifstream in(file);
  std::string line, text;
  for (int n = 1; std::getline(in, line); ++n) text += (n == line_no ? edit(line) : line) + "\n";
  in.close();
  std::ofstream(file) << text;
}

// Replaces the cell `column` (0-based) of a CSV line.
std::string SetCell(const std::string& line, int column, const std::string& value) {
  std::vector<std::string> cells;
  std::stringstream ss(line);
  std::string c;
  while (std::getline(ss, c, ',')) cells.push_back(c);
  cells.at(static_cast<std::size_t>(column)) = value;
  std::string out;
  for (std::size_t i = 0; i < cells.size(); ++i) out += (i ? "," : "") + cells[i];
  return out;
}

TEST_F(RoundTripTest, BadFileFailsItsStageNamingPositionAndKeepsTheOthers) {
  // Given the campaign with a non-numeric cell in bench.csv line 5, thrust column,
  ASSERT_EQ(synth_rc_, 0);
  const fs::path bad = CopyCampaign(dir_ / "c", dir_ / "bad");
  EditLine(bad / "bench.csv", 5, [](const std::string&) { return "0.36,15.0,4000,oops,0.02"; });
  // When identified,
  const fs::path out = bad / "vehicle.yaml";
  const int rc = RunApp(
      "sysid '" + (bad / "campaign.yaml").string() + "' -o '" + out.string() + "' --no-plots",
      bad / "sysid.log");
  // Then the propulsion stage fails naming file, line and column, the exit status says the
  // vehicle file is incomplete, and what the other stages identified is written,
  EXPECT_EQ(WEXITSTATUS(rc), 2);
  EXPECT_NE(Slurp(bad / "sysid.log").find("bench.csv:5:16: column 'thrust': not a number"),
            std::string::npos);
  ASSERT_TRUE(fs::exists(out));
  const std::string text = Slurp(out);
  EXPECT_NE(text.find("INCOMPLETE"), std::string::npos);
  EXPECT_EQ(text.find("thrust_constant"), std::string::npos);
  EXPECT_NE(text.find("inertia:"), std::string::npos);
  EXPECT_NE(text.find("attitude:"), std::string::npos);
  EXPECT_NE(text.find("attitude_pd:"), std::string::npos);
  EXPECT_THROW(config::LoadVehicleFile(out.string()), std::exception);
  const std::string summary = Slurp(bad / "vehicle.yaml.report" / "summary.json");
  EXPECT_NE(summary.find("\"complete\": false"), std::string::npos);
  EXPECT_NE(summary.find("not a number"), std::string::npos);
  // And a calibration with a flight whose time goes backwards fails naming the position.
  EditLine(bad / "flight.csv", 4, [](const std::string& l) { return "0" + l.substr(l.find(',')); });
  const int rc2 = RunApp("calibrate '" + (dir_ / "out" / "vehicle.yaml").string() + "' '" +
                             (bad / "flight.csv").string() + "' -o '" +
                             (bad / "cal.yaml").string() + "' --no-plots",
                         bad / "calibrate.log");
  EXPECT_NE(rc2, 0);
  EXPECT_NE(Slurp(bad / "calibrate.log").find("flight.csv:4:1: column 't'"), std::string::npos);
  EXPECT_FALSE(fs::exists(bad / "cal.yaml"));
}

TEST_F(RoundTripTest, MissingFilesFailOnlyTheirStages) {
  // Given the campaign without its optional flight,
  ASSERT_EQ(synth_rc_, 0);
  const fs::path c = CopyCampaign(dir_ / "c", dir_ / "noflight");
  fs::remove(c / "flight.csv");
  const std::string campaign = Slurp(c / "campaign.yaml");
  std::ofstream(c / "campaign.yaml")
      << campaign.substr(0, campaign.find("flight: flight.csv")) << "\n";
  // When identified, Then the vehicle file is complete,
  const int rc = RunApp("sysid '" + (c / "campaign.yaml").string() + "' -o '" +
                            (c / "vehicle.yaml").string() + "' --no-plots",
                        c / "sysid.log");
  EXPECT_TRUE(WEXITSTATUS(rc) == 0 || WEXITSTATUS(rc) == 3) << rc;
  EXPECT_NO_THROW(config::LoadVehicleFile((c / "vehicle.yaml").string()));
  // and without one pendulum run only the inertia stage fails.
  fs::remove(c / "pendulum_z.csv");
  const int rc2 = RunApp("sysid '" + (c / "campaign.yaml").string() + "' -o '" +
                             (c / "partial.yaml").string() + "' --no-plots",
                         c / "sysid2.log");
  EXPECT_EQ(WEXITSTATUS(rc2), 2);
  const std::string text = Slurp(c / "partial.yaml");
  EXPECT_EQ(text.find("inertia:"), std::string::npos);
  EXPECT_NE(text.find("thrust_constant:"), std::string::npos);
  EXPECT_NE(text.find("attitude:"), std::string::npos);
  EXPECT_NE(Slurp(c / "sysid2.log").find("pendulum_z.csv"), std::string::npos);
}

TEST_F(RoundTripTest, MissingFlightIsNamedAndACleanCampaignExitsZero) {
  // Given the clean synthetic campaign whose campaign file names a flight that is gone,
  ASSERT_EQ(synth_rc_, 0);
  const fs::path c = CopyCampaign(dir_ / "c", dir_ / "flightgone");
  fs::remove(c / "flight.csv");
  // When identified,
  const int rc = RunApp("sysid '" + (c / "campaign.yaml").string() + "' -o '" +
                            (c / "vehicle.yaml").string() + "' --no-plots",
                        c / "sysid.log");
  // Then it exits 0 (every stage ran, every check passed), the warning names the file, and
  // no solver (glog) line is in the output.
  EXPECT_EQ(WEXITSTATUS(rc), 0) << Slurp(c / "sysid.log");
  const std::string log = Slurp(c / "sysid.log");
  EXPECT_NE(log.find("flight.csv does not exist"), std::string::npos) << log;
  EXPECT_EQ(log.find("trust_region_minimizer"), std::string::npos) << log;
  EXPECT_NO_THROW(config::LoadVehicleFile((c / "vehicle.yaml").string()));
}

TEST_F(RoundTripTest, OutputPathReachesThePlotterWithoutAShell) {
  // Given an output name with quotes and a command substitution,
  ASSERT_EQ(synth_rc_, 0);
  const fs::path work = dir_ / "inject";
  fs::remove_all(work);
  fs::create_directories(work);
  const std::string evil = "out'$(touch PWNED)'.yaml";
  // When sysid and calibrate run with plots (the plotter is started) in that directory,
  // (the name is passed to the test's own shell in double quotes, with $ escaped)
  const std::string quoted = "\"out'\\$(touch PWNED)'.yaml\"";
  const std::string cmd_sysid = "cd '" + work.string() + "' && " + std::string(FNMPC_APP) +
                                " sysid '" + (dir_ / "c" / "campaign.yaml").string() + "' -o " +
                                quoted + " > sysid.log 2>&1";
  const int rc = std::system(cmd_sysid.c_str());
  const std::string cmd_cal = "cd '" + work.string() + "' && " + std::string(FNMPC_APP) +
                              " calibrate " + quoted + " '" + (dir_ / "c" / "flight.csv").string() +
                              "' -o " + quoted + ".cal > calibrate.log 2>&1";
  const int rc2 = std::system(cmd_cal.c_str());
  // Then nothing was executed, and the files carry the name verbatim.
  EXPECT_FALSE(fs::exists(work / "PWNED"));
  EXPECT_TRUE(WEXITSTATUS(rc) == 0 || WEXITSTATUS(rc) == 3) << Slurp(work / "sysid.log");
  EXPECT_EQ(WEXITSTATUS(rc2), 0) << Slurp(work / "calibrate.log");
  EXPECT_TRUE(fs::exists(work / evil));
  EXPECT_TRUE(fs::exists(work / (evil + ".report") / "summary.json"));
  EXPECT_TRUE(fs::exists(work / (evil + ".cal")));
}

TEST_F(RoundTripTest, HugeYawDoesNotHang) {
  // Given a yaw of 1e17 rad in one sample of the attitude steps and of the flight,
  ASSERT_EQ(synth_rc_, 0);
  const fs::path c = CopyCampaign(dir_ / "c", dir_ / "hugeyaw");
  EditLine(c / "attitude_steps.csv", 40,
           [](const std::string& l) { return SetCell(l, 6, "1e17"); });
  EditLine(c / "flight.csv", 40, [](const std::string& l) { return SetCell(l, 9, "-3e18"); });
  // When identified and calibrated (each bounded by `timeout`: an angle unwrap stepping by
  // 2 pi would never end),
  const int rc = RunApp("sysid '" + (c / "campaign.yaml").string() + "' -o '" +
                            (c / "vehicle.yaml").string() + "' --no-plots",
                        c / "sysid.log", 120);
  const int rc2 = RunApp("calibrate '" + (dir_ / "out" / "vehicle.yaml").string() + "' '" +
                             (c / "flight.csv").string() + "' -o '" + (c / "cal.yaml").string() +
                             "' --no-plots",
                         c / "calibrate.log", 120);
  // Then both finish (with a result or an error, not killed by the timeout).
  EXPECT_NE(WEXITSTATUS(rc), 124);
  EXPECT_NE(WEXITSTATUS(rc2), 124);
}

}  // namespace
}  // namespace fnmpc

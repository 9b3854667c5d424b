// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc import-ulog` end to end (docs/ulog.md): on the SITL log and two real logs of
// ../shared/px4-logs (read in place), the written files are read back with the campaign CSV
// reader that `fnmpc sysid` / `fnmpc calibrate` use (config::ReadCsv, the same required
// columns), the frames are checked physically (ENU position against integrated velocity, the
// world acceleration against the ENU/FLU tilt), the hover thrust of the SITL flight against
// the simulated vehicle's truth; a log without a needed topic and a file that is not ULog
// exit 1 with a message naming what is missing (docs/failure.md).
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "fnmpc/config/csv_reader.hpp"
#include "tests/ulog/ulog_builder.hpp"

namespace fnmpc::ulog {
namespace {

namespace fs = std::filesystem;
const fs::path kLogs = fs::path(FNMPC_SOURCE_DIR) / ".." / "shared" / "px4-logs";
const std::vector<std::string> kStepColumns{"t",    "roll_ref", "pitch_ref", "yaw_ref",
                                            "roll", "pitch",    "yaw"};
const std::vector<std::string> kFlightColumns{
    "t",     "x",   "y",          "z",        "vx",        "vy",      "vz",     "roll",
    "pitch", "yaw", "thrust_cmd", "roll_cmd", "pitch_cmd", "yaw_cmd", "voltage"};

struct CommandResult {
  int code = -1;
  std::string out, err;
};

std::string Slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

CommandResult Import(const fs::path& log, const fs::path& dir, const std::string& extra = "") {
  fs::remove_all(dir);
  const fs::path out = dir.string() + ".stdout", err = dir.string() + ".stderr";
  const std::string cmd = std::string("'") + FNMPC_APP + "' import-ulog '" + log.string() +
                          "' -o '" + dir.string() + "' " + extra + " >'" + out.string() + "' 2>'" +
                          err.string() + "'";
  const int status = std::system(cmd.c_str());
  CommandResult r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = Slurp(out);
  r.err = Slurp(err);
  return r;
}

double Correlation(const std::vector<double>& a, const std::vector<double>& b) {
  double ma = 0, mb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) ma += a[i], mb += b[i];
  ma /= a.size();
  mb /= b.size();
  double sab = 0, saa = 0, sbb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

TEST(ImportUlog, SitlLogGivesCampaignFilesInProjectFramesAndTheHoverThrust) {
  const fs::path dir = fs::temp_directory_path() / "fnmpc_import_ulog_sitl";
  const CommandResult r = Import(kLogs / "sitl" / "sih_quadx_sysid_a.ulg", dir, "--mass 1.0");
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("SYS_AUTOSTART 10040"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("in air: 4219.83-4259.93"), std::string::npos) << r.out;

  // Readable by the campaign reader with the columns sysid and calibrate require.
  const config::CsvTable steps =
      config::ReadCsv((dir / "attitude_steps.csv").string(), kStepColumns, "t");
  const config::CsvTable flight =
      config::ReadCsv((dir / "flight.csv").string(), kFlightColumns, "t");
  EXPECT_GT(steps.rows(), 10000u);
  EXPECT_GT(flight.rows(), 3000u);
  // The attitude loop tracks its reference, some 0.2 s behind (266 Hz rows): same frame and
  // sign for both. Best correlation over lags of 0 to 0.56 s.
  for (const char* axis : {"roll", "pitch"}) {
    const auto& y = steps.Column(axis);
    const auto& ref = steps.Column(std::string(axis) + "_ref");
    double best = -1;
    for (std::size_t lag = 0; lag <= 150; lag += 10) {
      const std::vector<double> a(y.begin() + static_cast<long>(lag), y.end());
      const std::vector<double> b(ref.begin(), ref.end() - static_cast<long>(lag));
      best = std::max(best, Correlation(a, b));
    }
    EXPECT_GT(best, 0.9) << axis;
  }
  // ENU position and ENU velocity agree: the position's rate of change correlates with the
  // velocity on every axis (a sign error or swapped axes would give -1 or ~0); z is up (the
  // flight is at ~1 m).
  const auto& t = flight.Column("t");
  for (const char* axis : {"x", "y", "z"}) {
    const auto& p = flight.Column(axis);
    const auto& v = flight.Column(std::string("v") + axis);
    std::vector<double> rate, velocity;
    for (std::size_t i = 10; i + 10 < t.size(); i += 10) {
      rate.push_back((p[i + 10] - p[i - 10]) / (t[i + 10] - t[i - 10]));
      velocity.push_back(v[i]);
    }
    EXPECT_GT(Correlation(rate, velocity), 0.95) << axis;
  }
  double z_mean = 0;
  for (double z : flight.Column("z")) z_mean += z / flight.rows();
  EXPECT_GT(z_mean, 0.5);
  // Small-angle ENU/FLU kinematics: world acceleration x ~ g (pitch cos yaw + roll sin yaw),
  // y ~ g (pitch sin yaw - roll cos yaw); a wrong sign of any angle breaks the correlation.
  std::vector<double> ax, ay, predicted_x, predicted_y;
  const auto &vx = flight.Column("vx"), &vy = flight.Column("vy");
  const auto &roll = flight.Column("roll"), &pitch = flight.Column("pitch"),
             &yaw = flight.Column("yaw");
  for (std::size_t i = 5; i + 5 < t.size(); i += 5) {
    const double dt = t[i + 5] - t[i - 5];
    ax.push_back((vx[i + 5] - vx[i - 5]) / dt);
    ay.push_back((vy[i + 5] - vy[i - 5]) / dt);
    predicted_x.push_back(9.81 * (pitch[i] * std::cos(yaw[i]) + roll[i] * std::sin(yaw[i])));
    predicted_y.push_back(9.81 * (pitch[i] * std::sin(yaw[i]) - roll[i] * std::cos(yaw[i])));
  }
  EXPECT_GT(Correlation(ax, predicted_x), 0.7);
  EXPECT_GT(Correlation(ay, predicted_y), 0.7);

  // Hover thrust against the simulated vehicle (truth.yaml: hover_command = m g / (4 T_max)).
  const std::string truth = Slurp(kLogs / "sitl" / "truth.yaml");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(truth, m, std::regex(R"(hover_command:\s*([0-9.]+))")));
  const double hover_truth = std::stod(m[1]);
  const nlohmann::json summary = nlohmann::json::parse(Slurp(dir / "summary.json"));
  const double hover = summary["hover"]["thrust_normalised"].get<double>();
  const double motors = summary["hover"]["motor_command_mean"].get<double>();
  std::printf("SITL hover thrust %.4f (motors %.4f) vs truth %.4f: %+.2f %%\n", hover, motors,
              hover_truth, 100 * (hover / hover_truth - 1));
  EXPECT_NEAR(hover / hover_truth, 1.0, 0.02);
  EXPECT_NEAR(motors / hover_truth, 1.0, 0.02);
  // thrust_cmd [N] = mass g u / u_hover: hovering it is the weight.
  EXPECT_NEAR(summary["thrust_cmd_scale_N"].get<double>() * hover, 9.80665, 1e-9);
  EXPECT_EQ(summary["vehicle"]["parameters"]["CA_ROTOR_COUNT"].get<double>(), 4.0);
  EXPECT_TRUE(summary["reader_warnings"].empty());
}

TEST(ImportUlog, RealLogsImportAndSayWhatIsMissing) {
  const fs::path dir = fs::temp_directory_path() / "fnmpc_import_ulog_brownout";
  const CommandResult r = Import(kLogs / "real" / "battery_brownout.ulg", dir, "--mass 2.0");
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("PX4 v1.15.1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("MPC_THR_HOVER=0.58"), std::string::npos) << r.out;
  const config::CsvTable steps =
      config::ReadCsv((dir / "attitude_steps.csv").string(), kStepColumns, "t");
  const config::CsvTable flight =
      config::ReadCsv((dir / "flight.csv").string(), kFlightColumns, "t");
  EXPECT_GT(steps.rows(), 1000u);
  EXPECT_GT(flight.rows(), 500u);
  for (double v : flight.Column("voltage")) EXPECT_EQ(v, 0.0);  // no battery monitor
  EXPECT_NE(r.out.find("no battery voltage in the log"), std::string::npos) << r.out;

  // The PX4 1.9 log (actuator_controls_0, rates in vehicle_attitude); no --mass: no flight.csv.
  const fs::path old = fs::temp_directory_path() / "fnmpc_import_ulog_old";
  const CommandResult o = Import(kLogs / "real" / "motor_failure.ulg", old);
  ASSERT_EQ(o.code, 0) << o.out << o.err;
  EXPECT_NE(o.out.find("PX4 v1.9.0 beta"), std::string::npos) << o.out;
  EXPECT_GT(config::ReadCsv((old / "attitude_steps.csv").string(), kStepColumns, "t").rows(),
            1000u);
  EXPECT_FALSE(fs::exists(old / "flight.csv"));
  EXPECT_NE(o.out.find("flight.csv not written"), std::string::npos) << o.out;
  EXPECT_TRUE(fs::exists(old / "summary.json"));
}

TEST(ImportUlog, TruncatedLogIsImportedUpToTheCutWithItsOffset) {
  // The SITL log cut at 7 MB (mid-flight, inside a data message at offset 6999899).
  const fs::path cut = fs::temp_directory_path() / "fnmpc_import_ulog_cut.ulg";
  {
    std::ifstream in(kLogs / "sitl" / "sih_quadx_sysid_a.ulg", std::ios::binary);
    std::vector<char> head(7000000);
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    std::ofstream(cut, std::ios::binary | std::ios::trunc)
        .write(head.data(), static_cast<std::streamsize>(head.size()));
  }
  const fs::path dir = fs::temp_directory_path() / "fnmpc_import_ulog_cut";
  const CommandResult r = Import(cut, dir, "--mass 1.0");
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("TRUNCATED"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("warning: offset 6999899: truncated: the file ends inside a 'D' message"),
            std::string::npos)
      << r.out;
  const nlohmann::json summary = nlohmann::json::parse(Slurp(dir / "summary.json"));
  EXPECT_TRUE(summary["truncated"].get<bool>());
  EXPECT_GT(config::ReadCsv((dir / "flight.csv").string(), kFlightColumns, "t").rows(), 1000u);
}

TEST(ImportUlog, MissingTopicOrNotULogExitsOneNamingIt) {
  testing::Builder b;
  b.FlagBits(0);
  b.Format("vehicle_attitude:uint64_t timestamp;float[4] q;");
  b.Format("vehicle_attitude_setpoint:uint64_t timestamp;float[4] q_d;float[3] thrust_body;");
  b.Add(0, 0, "vehicle_attitude");
  b.Add(0, 1, "vehicle_attitude_setpoint");
  for (int i = 0; i < 20; ++i) {
    testing::Bytes a;
    testing::Put(a, std::uint64_t(1000 + 1000 * i));
    for (float q : {1.0f, 0.0f, 0.0f, 0.0f}) testing::Put(a, q);
    b.Data(0, a);
    testing::Bytes sp = a;
    for (float f : {0.0f, 0.0f, -0.5f}) testing::Put(sp, f);
    b.Data(1, sp);
  }
  const fs::path log = fs::temp_directory_path() / "fnmpc_import_ulog_missing.ulg";
  {
    std::ofstream f(log, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(b.bytes().data()),
            static_cast<std::streamsize>(b.size()));
  }
  const fs::path dir = fs::temp_directory_path() / "fnmpc_import_ulog_missing";
  const CommandResult r = Import(log, dir);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("topic 'vehicle_local_position' is not in the log (needed for flight.csv)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "attitude_steps.csv"));

  const fs::path text = fs::temp_directory_path() / "fnmpc_import_ulog_text.ulg";
  std::ofstream(text) << "time,x\n0,1\n";
  const CommandResult t = Import(text, dir);
  EXPECT_EQ(t.code, 1);
  EXPECT_NE(t.err.find("offset 0: not a ULog file"), std::string::npos) << t.err;
}

}  // namespace
}  // namespace fnmpc::ulog

// SPDX-License-Identifier: BSD-3-Clause
// Every input checked at the boundary, with file, line and key (docs/failure.md "Input checks
// and limits"). Each test below fails without its check (no error, a hang, or an error without
// a place).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>

#include "fnmpc/config/csv_reader.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/config/sensors_yaml.hpp"
#include "fnmpc/config/text_file.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "scenario_text.hpp"

namespace fnmpc::config {
namespace {

using test::ShippedScenarioText;

/// The text with the first occurrence of `from` replaced by `to` (which must occur).
std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const auto p = text.find(from);
  EXPECT_NE(p, std::string::npos) << from;
  if (p != std::string::npos) text.replace(p, from.size(), to);
  return text;
}

std::string ScenarioError(const std::string& text) {
  try {
    ParseScenario(YamlMap::LoadString(text, "s.yaml"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string VehicleError(const std::string& text) {
  try {
    ParseVehicle(YamlMap::LoadString(text, "v.yaml"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string SensorsError(const std::string& text) {
  try {
    ParseSensors(YamlMap::LoadString(text, "x.yaml"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string FileText(const std::string& path) { return ReadTextFile(path); }

const std::string kVehicle = std::string(FNMPC_SOURCE_DIR) + "/config/vehicles/storm-drone-4.yaml";
const std::string kTriangle = "triangle.yaml";

// ---- Duplicate keys.
TEST(ErrorPlaceTest, SplitsFileLineColumnAndKey) {
  // The first ":<line>:<column>: " ends the file name, which may contain ':' itself.
  const ErrorPlace e = ParseErrorPlace("dir:a/b.yaml:12:3: key 'vehicles[1].mass': must be > 0");
  EXPECT_TRUE(e.placed);
  EXPECT_EQ(e.file, "dir:a/b.yaml");
  EXPECT_EQ(e.line, 12);
  EXPECT_EQ(e.column, 3);
  EXPECT_EQ(e.key, "vehicles[1].mass");
  EXPECT_EQ(e.what, "key 'vehicles[1].mass': must be > 0");
  const ErrorPlace n = ParseErrorPlace("x.yaml: cannot open file (No such file or directory)");
  EXPECT_FALSE(n.placed);
  EXPECT_TRUE(n.key.empty());
  EXPECT_FALSE(ParseErrorPlace("x.yaml:12: no column").placed);
  EXPECT_FALSE(ParseErrorPlace("x.yaml:1:2 missing the space after the colon").placed);
}

TEST(InputHardeningTest, DuplicateKeyIsRejectedNamingBothLines) {
  const std::string text = FileText(kVehicle) + "mass: -5\n";
  const std::string e = VehicleError(text);
  EXPECT_NE(e.find("duplicate key"), std::string::npos) << e;
  EXPECT_NE(e.find("key 'mass'"), std::string::npos) << e;
  EXPECT_NE(e.find("(first at line 3)"), std::string::npos) << e;
  EXPECT_EQ(e.rfind("v.yaml:", 0), 0u) << e;
}

TEST(InputHardeningTest, DuplicateKeyInANestedMappingIsRejected) {
  const std::string e = ScenarioError(
      Replace(ShippedScenarioText(kTriangle), "  horizon: 15\n", "  horizon: 15\n  horizon: 20\n"));
  EXPECT_NE(e.find("key 'horizon': duplicate key (first at line"), std::string::npos) << e;
}

// ---- Only regular files, errno text.
TEST(InputHardeningTest, DirectoryIsRefusedAsAFile) {
  const std::string e = [] {
    try {
      YamlMap::LoadFile(FNMPC_SOURCE_DIR);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  }();
  EXPECT_NE(e.find("is a directory"), std::string::npos) << e;
}

TEST(InputHardeningTest, MissingFileNamesTheErrnoText) {
  try {
    YamlMap::LoadFile("/nonexistent/fnmpc.yaml");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("No such file or directory"), std::string::npos)
        << e.what();
  }
}

TEST(InputHardeningTest, DevicesAndFifosAreRefusedWithoutReading) {
  const std::string fifo = testing::TempDir() + "/fnmpc-fifo-" + std::to_string(getpid());
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto t0 = std::chrono::steady_clock::now();
  for (const std::string& path : {std::string("/dev/zero"), std::string("/dev/urandom"), fifo}) {
    try {
      YamlMap::LoadFile(path);
      ADD_FAILURE() << path << " was read";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
    }
    EXPECT_THROW(ReadCsv(path, {"t"}), ConfigError) << path;
  }
  // Refused at once (a blocking open of the FIFO or reading /dev/zero would never return).
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));
  ::unlink(fifo.c_str());
}

TEST(InputHardeningTest, TooLargeFileIsRefused) {
  const std::string path = testing::TempDir() + "/fnmpc-large-" + std::to_string(getpid());
  {
    std::FILE* f = std::fopen(path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    const std::string line(1000, 'x');
    for (int i = 0; i < 3; ++i) std::fputs(line.c_str(), f);
    std::fclose(f);
  }
  EXPECT_THROW(ReadTextFile(path, 2000), ConfigError);
  EXPECT_EQ(ReadTextFile(path, 4000).size(), 3000u);
  std::remove(path.c_str());
}

// ---- Names are identifiers, UTF-8 checked.
TEST(InputHardeningTest, VehicleNameWithAPathIsRejectedAtParseTime) {
  const std::string e = ScenarioError(
      Replace(ShippedScenarioText(kTriangle), "  - name: leader", "  - name: ../../pwned"));
  EXPECT_NE(e.find("key 'vehicles[0].name'"), std::string::npos) << e;
  EXPECT_NE(e.find("s.yaml:12:"), std::string::npos) << e;
}

TEST(InputHardeningTest, ScenarioNameWithAPathIsRejected) {
  const std::string e =
      ScenarioError(Replace(ShippedScenarioText(kTriangle), "name: triangle", "name: ../../x"));
  EXPECT_NE(e.find("key 'name'"), std::string::npos) << e;
}

TEST(InputHardeningTest, InvalidUtf8IsRejectedWithItsLine) {
  const std::string e = ScenarioError(
      Replace(ShippedScenarioText(kTriangle), "  - name: leader", "  - name: lea\xff\xfe"));
  EXPECT_NE(e.find("s.yaml:12:"), std::string::npos) << e;
  EXPECT_NE(e.find("invalid UTF-8"), std::string::npos) << e;
  EXPECT_TRUE(IsIdentifier("follower_2-b"));
  EXPECT_FALSE(IsIdentifier("caf\xc3\xa9"));
  EXPECT_FALSE(IsIdentifier(""));
  EXPECT_EQ(FindInvalidUtf8("caf\xc3\xa9"), std::string::npos);
  EXPECT_EQ(FindInvalidUtf8("\xc0\xaf"), 0u);  // overlong '/'
}

// ---- Nonsense values refused.
TEST(InputHardeningTest, NanWaypointIsRejected) {
  const std::string e = ScenarioError(
      Replace(ShippedScenarioText(kTriangle), "- [1.5, 0.0, 0.5]", "- [1.5, .nan, 0.5]"));
  EXPECT_NE(e.find("key 'leader.waypoints[0]'"), std::string::npos) << e;
  EXPECT_NE(e.find("finite"), std::string::npos) << e;
}

TEST(InputHardeningTest, HugeDurationStepsAndMovesAreRejected) {
  EXPECT_NE(
      ScenarioError(Replace(ShippedScenarioText(kTriangle), "duration: 82.0", "duration: 3e6"))
          .find("key 'duration'"),
      std::string::npos);
  EXPECT_NE(ScenarioError(Replace(ShippedScenarioText(kTriangle), "integrator_steps: 2",
                                  "integrator_steps: 100000000"))
                .find("key 'controller.integrator_steps'"),
            std::string::npos);
  const std::string manual = ShippedScenarioText("manual-leader.yaml");
  const std::string e = ScenarioError(Replace(manual, "moves: 8", "moves: 1000000000"));
  EXPECT_NE(e.find("key 'leader.moves'"), std::string::npos) << e;
}

TEST(InputHardeningTest, SampleTimeMustBeAMultipleOfThePhysicsStep) {
  const std::string e = ScenarioError(
      Replace(ShippedScenarioText(kTriangle), "sample_time: 0.05", "sample_time: 0.0015"));
  EXPECT_NE(e.find("key 'controller.sample_time'"), std::string::npos) << e;
  EXPECT_EQ(ScenarioError(
                Replace(ShippedScenarioText(kTriangle), "sample_time: 0.05", "sample_time: 0.04")),
            "");
}

TEST(InputHardeningTest, ThrustBoundsThatCannotLiftTheVehicleAreRejected) {
  const std::string e = ScenarioError(
      Replace(ShippedScenarioText(kTriangle), "thrust: [5.0, 25.0]", "thrust: [0, 1]"));
  EXPECT_NE(e.find("key 'controller.bounds.thrust'"), std::string::npos) << e;
}

TEST(InputHardeningTest, SameNeighbourTwiceIsRejected) {
  const std::string e = ScenarioError(Replace(ShippedScenarioText(kTriangle),
                                              "{vehicle: follower2, desired: [0.0, -3.0, 0.0]}",
                                              "{vehicle: leader, desired: [0.0, -3.0, 0.0]}"));
  EXPECT_NE(e.find("listed twice"), std::string::npos) << e;
  EXPECT_NE(e.find("key 'vehicles[1].neighbours[1].vehicle'"), std::string::npos) << e;
}

TEST(InputHardeningTest, LeaderWithoutMocapAndUnreachableNeighbourAreWarned) {
  const std::string dir = testing::TempDir() + "/fnmpc-warn-" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  {
    std::FILE* f = std::fopen((dir + "/blind.yaml").c_str(), "w");
    std::fputs("mocap: {enabled: false}\nrelative: {max_range: 2.0}\n", f);
    std::fclose(f);
  }
  std::string text = Replace(ShippedScenarioText(kTriangle), "    start: [0.0, 0.0]",
                             "    start: [0.0, 0.0]\n    sensors_file: " + dir + "/blind.yaml");
  text = Replace(text, "    start: [-2.0, 1.5]",
                 "    start: [-2.0, 1.5]\n    sensors_file: " + dir + "/blind.yaml");
  const ScenarioConfig s = ParseScenario(YamlMap::LoadString(text, "s.yaml"));
  ASSERT_EQ(s.warnings.size(), 3u);  // leader blind; follower1: leader 2.5 m, follower2 3 m
  std::string all;
  for (const auto& w : s.warnings) all += w + "\n";
  EXPECT_NE(all.find("no absolute position sensing"), std::string::npos) << all;
  EXPECT_NE(all.find("beyond the relative sensor's max_range"), std::string::npos) << all;
  EXPECT_NE(all.find("key 'vehicles[1].neighbours[0].vehicle'"), std::string::npos) << all;
  // A desired offset outside the follower's relative-position bound is warned, at its key.
  const ScenarioConfig far = ParseScenario(YamlMap::LoadString(
      Replace(ShippedScenarioText(kTriangle),
              "    start: [-2.0, 1.5]\n    frame: m\n    relative_position_bound: [4.0, 4.0, 1.5]",
              "    start: [-2.0, 1.5]\n    frame: m\n    relative_position_bound: [1.0, 4.0, 1.5]"),
      "s.yaml"));
  std::string far_all;
  for (const auto& w : far.warnings) far_all += w + "\n";
  EXPECT_NE(far_all.find("outside its relative_position_bound (1, 4, 1.5) m"), std::string::npos)
      << far_all;
  EXPECT_NE(far_all.find(".desired'"), std::string::npos) << far_all;
  // The shipped scenario has none.
  EXPECT_TRUE(ParseScenario(YamlMap::LoadString(ShippedScenarioText(kTriangle), "s.yaml"))
                  .warnings.empty());
  std::filesystem::remove_all(dir);
}

TEST(InputHardeningTest, DurationFlagIsChecked) {
  const ScenarioConfig s =
      ParseScenario(YamlMap::LoadString(ShippedScenarioText(kTriangle), "s.yaml"));
  for (double d : {0.0, -5.0, std::nan(""), std::numeric_limits<double>::infinity(), 200.0}) {
    EXPECT_THROW(CheckDurationFlag(s, d), ConfigError) << d;
  }
  EXPECT_NO_THROW(CheckDurationFlag(s, 30.0));
}

TEST(InputHardeningTest, EnvelopeBlockIsReadAndChecked) {
  const std::string base = ShippedScenarioText(kTriangle);
  const ScenarioConfig s = ParseScenario(
      YamlMap::LoadString(base + "envelope: {max_altitude: 3.0, max_distance: 9.0}\n", "s.yaml"));
  EXPECT_DOUBLE_EQ(s.envelope.max_altitude, 3.0);
  EXPECT_DOUBLE_EQ(s.envelope.max_distance, 9.0);
  EXPECT_NE(
      ScenarioError(base + "envelope: {max_altitude: -1}\n").find("key 'envelope.max_altitude'"),
      std::string::npos);
}

// ---- Sensors: rates bounded (a 1e9 Hz rate stepped one index at a time), noise > 0.
TEST(InputHardeningTest, SensorRateAndZeroNoiseAreRejectedWithTheirKey) {
  std::string e = SensorsError("imu: {rate_hz: 1.0e9}\n");
  EXPECT_NE(e.find("x.yaml:1:"), std::string::npos) << e;
  EXPECT_NE(e.find("key 'imu.rate_hz'"), std::string::npos) << e;
  e = SensorsError("mocap:\n  position_noise: [0, 0.001, 0.001]\n");
  EXPECT_NE(e.find("key 'mocap.position_noise'"), std::string::npos) << e;
  e = SensorsError("relative: {range_noise: 0}\n");
  EXPECT_NE(e.find("key 'relative.range_noise'"), std::string::npos) << e;
}

// ---- Vehicle plausibility (check-vehicle and every load).
TEST(InputHardeningTest, ImplausibleVehiclesAreRejected) {
  const std::string shipped = FileText(kVehicle);
  std::string e = VehicleError(Replace(shipped, "mass: 1.37", "mass: 1e300"));
  EXPECT_NE(e.find("key 'mass'"), std::string::npos) << e;
  // Hover throttle -0.9 and about 90: the constant term shifted.
  for (const std::string c0 : {"-1.2", "90.0"}) {
    e = VehicleError(Replace(shipped, "- [1.295532269,", "- [" + c0 + ","));
    EXPECT_NE(e.find("key 'throttle_polynomial'"), std::string::npos) << c0 << ": " << e;
    EXPECT_NE(e.find("hover throttle"), std::string::npos) << c0 << ": " << e;
  }
  // Full throttle below 1.2 x hover: a vehicle four times heavier.
  e = VehicleError(Replace(shipped, "mass: 1.37", "mass: 5.0"));
  EXPECT_NE(e.find("key 'throttle_polynomial'"), std::string::npos) << e;
  // A value the model rejects names its key (it was "[VehicleParams] attitude.gain ...").
  e = VehicleError(Replace(shipped, "gain: [1.01, 1.02, 0.99]", "gain: [0.0, 1.02, 0.99]"));
  EXPECT_NE(e.find("key 'attitude.gain'"), std::string::npos) << e;
  e = VehicleError(Replace(shipped, "- [0.0003812494858]", "- [.nan]"));
  EXPECT_NE(e.find("key 'throttle_polynomial.coefficients'"), std::string::npos) << e;
  EXPECT_EQ(VehicleError(shipped), "");
}

}  // namespace
}  // namespace fnmpc::config

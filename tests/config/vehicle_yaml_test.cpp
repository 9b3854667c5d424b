// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/vehicle_yaml.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

namespace fnmpc::config {
namespace {

const std::string kShipped = std::string(FNMPC_SOURCE_DIR) + "/config/vehicles/storm-drone-4.yaml";

std::string ErrorOf(const std::string& text) {
  try {
    ParseVehicle(YamlMap::LoadString(text, "v.yaml"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string ShippedText() {
  FILE* f = std::fopen(kShipped.c_str(), "r");
  std::string s;
  char buf[4096];
  size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) s.append(buf, n);
  std::fclose(f);
  return s;
}

TEST(VehicleYamlTest, ShippedFileHasReferenceValues) {
  const auto p = LoadVehicleFile(kShipped);
  EXPECT_DOUBLE_EQ(p.mass, 1.37);
  EXPECT_DOUBLE_EQ(p.inertia.y(), 0.0136);
  EXPECT_DOUBLE_EQ(p.thrust_constant, 9.803e-8);
  EXPECT_DOUBLE_EQ(p.attitude_time_constant.z(), 0.0651);
  EXPECT_DOUBLE_EQ(p.attitude_gain.x(), 1.01);
  EXPECT_FALSE(p.has_bias);
  // Hover: one rotor carries m g / 4; the polynomial must give a mid-range throttle and
  // invert back to the same thrust.
  const double f = p.mass * 9.81 / 4.0;
  const double throttle = p.throttle.Throttle(f, 16.0);
  EXPECT_GT(throttle, 0.3);
  EXPECT_LT(throttle, 0.7);
  EXPECT_NEAR(p.throttle.Thrust(throttle, 16.0), f, 1e-9);
  // Lower voltage needs more throttle for the same thrust.
  EXPECT_GT(p.throttle.Throttle(f, 15.0), throttle);
}

TEST(VehicleYamlTest, RoundTripThroughSave) {
  auto p = LoadVehicleFile(kShipped);
  p.has_bias = true;
  p.bias.roll = 0.02;
  p.bias.thrust_scale = 0.97;
  const auto path = std::filesystem::temp_directory_path() /
                    ("fnmpc_vehicle_roundtrip_" + std::to_string(getpid()) + ".yaml");
  SaveVehicleFile(p, path.string());
  const auto q = LoadVehicleFile(path.string());
  EXPECT_TRUE(q.has_bias);
  EXPECT_DOUBLE_EQ(q.bias.roll, 0.02);
  EXPECT_DOUBLE_EQ(q.bias.thrust_scale, 0.97);
  EXPECT_TRUE(q.throttle.c.isApprox(p.throttle.c, 1e-9));
  std::filesystem::remove(path);
}

TEST(VehicleYamlTest, UnknownKeyNamesLineAndKey) {
  std::string text = ShippedText() + "rotor_count: 4\n";
  const std::string err = ErrorOf(text);
  EXPECT_NE(err.find("unknown key 'rotor_count'"), std::string::npos) << err;
  EXPECT_NE(err.find("v.yaml:20:"), std::string::npos) << err;
}

TEST(VehicleYamlTest, MissingKeyIsNamed) {
  std::string text = ShippedText();
  text.replace(text.find("mass: 1.37"), 10, "weight: 1.37");
  const std::string err = ErrorOf(text);
  EXPECT_NE(err.find("'mass': missing required key"), std::string::npos) << err;
}

TEST(VehicleYamlTest, MistypedValueNamesLineAndKey) {
  std::string text = ShippedText();
  text.replace(text.find("[1.01, 1.02, 0.99]"), 18, "[1.01, fast, 0.99]");
  const std::string err = ErrorOf(text);
  EXPECT_NE(err.find("attitude.gain"), std::string::npos) << err;
  EXPECT_NE(err.find("v.yaml:15:"), std::string::npos) << err;
}

TEST(VehicleYamlTest, NonPhysicalValueRejected) {
  std::string text = ShippedText();
  text.replace(text.find("mass: 1.37"), 10, "mass: -1.0");
  // Named by its file, line and key, not as "[VehicleParams] mass must be ...".
  EXPECT_NE(ErrorOf(text).find("v.yaml:3:7: key 'mass': must be > 0"), std::string::npos)
      << ErrorOf(text);
}

TEST(VehicleYamlTest, WrongPolynomialShapeRejected) {
  std::string text = ShippedText();
  text.replace(text.find("- [0.0003812494858]"), 19, "- [0.0003812494858, 1.0]");
  EXPECT_NE(ErrorOf(text).find("row 3 must hold 1 numbers"), std::string::npos);
}

TEST(VehicleYamlTest, MissingFileAndSyntaxError) {
  EXPECT_THROW(LoadVehicleFile("/nonexistent/vehicle.yaml"), ConfigError);
  const std::string err = ErrorOf("mass: [1, 2\n");
  EXPECT_NE(err.find("YAML syntax error"), std::string::npos) << err;
}

}  // namespace
}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/sensors_yaml.hpp"

#include <gtest/gtest.h>

#include <string>

namespace fnmpc::config {
namespace {

std::string ErrorOf(const std::string& text) {
  try {
    ParseSensors(YamlMap::LoadString(text, "s.yaml"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

void ExpectSame(const SensorSpec& a, const SensorSpec& b) {
  EXPECT_EQ(a.enabled, b.enabled);
  EXPECT_DOUBLE_EQ(a.rate_hz, b.rate_hz);
  EXPECT_DOUBLE_EQ(a.latency_s, b.latency_s);
  EXPECT_DOUBLE_EQ(a.dropout_probability, b.dropout_probability);
  EXPECT_TRUE(a.noise.isApprox(b.noise, 1e-12) || a.noise == b.noise);
  EXPECT_TRUE(a.noise2.isApprox(b.noise2, 1e-12) || a.noise2 == b.noise2);
  EXPECT_DOUBLE_EQ(a.range_noise_growth, b.range_noise_growth);
  EXPECT_DOUBLE_EQ(a.max_range, b.max_range);
  EXPECT_NEAR(a.field_of_view, b.field_of_view, 1e-12);
}

TEST(SensorsYamlTest, ShippedDefaultEqualsStructDefaults) {
  // Given the shipped default file, Then it parses to exactly SensorsConfig{}.
  const SensorsConfig c =
      LoadSensorsFile(std::string(FNMPC_SOURCE_DIR) + "/config/sensors/default.yaml");
  const SensorsConfig d;
  ExpectSame(c.mocap, d.mocap);
  ExpectSame(c.imu, d.imu);
  ExpectSame(c.optical_flow, d.optical_flow);
  ExpectSame(c.compass, d.compass);
  ExpectSame(c.battery, d.battery);
  ExpectSame(c.relative, d.relative);
}

TEST(SensorsYamlTest, PartialFileKeepsDefaults) {
  // Given only a few keys, Then those change and the rest keep their defaults.
  const SensorsConfig c = ParseSensors(
      YamlMap::LoadString("mocap:\n  rate_hz: 120\n  position_noise: [0.002, 0.002, 0.003]\n"
                          "relative:\n  enabled: false\n  max_range: 4.0\n",
                          "s.yaml"));
  EXPECT_DOUBLE_EQ(c.mocap.rate_hz, 120.0);
  EXPECT_DOUBLE_EQ(c.mocap.noise.z(), 0.003);
  EXPECT_DOUBLE_EQ(c.mocap.latency_s, SensorsConfig{}.mocap.latency_s);
  EXPECT_FALSE(c.relative.enabled);
  EXPECT_DOUBLE_EQ(c.relative.max_range, 4.0);
  EXPECT_DOUBLE_EQ(c.imu.rate_hz, 250.0);
}

TEST(SensorsYamlTest, ErrorsNameLineAndKey) {
  // Unknown sensor name.
  std::string err = ErrorOf("mocap:\n  rate_hz: 60\nlidar:\n  rate_hz: 10\n");
  EXPECT_NE(err.find("s.yaml:3:"), std::string::npos) << err;
  EXPECT_NE(err.find("unknown key 'lidar'"), std::string::npos) << err;
  // Unknown key inside a sensor.
  err = ErrorOf("imu:\n  rate_hz: 250\n  gyro_bias: 0.1\n");
  EXPECT_NE(err.find("s.yaml:3:"), std::string::npos) << err;
  EXPECT_NE(err.find("unknown key 'imu.gyro_bias'"), std::string::npos) << err;
  // Rates <= 0.
  err = ErrorOf("compass:\n  rate_hz: 0\n");
  EXPECT_NE(err.find("s.yaml:2:"), std::string::npos) << err;
  EXPECT_NE(err.find("'compass.rate_hz': must be > 0"), std::string::npos) << err;
  EXPECT_NE(ErrorOf("relative:\n  rate_hz: -50\n").find("must be > 0"), std::string::npos);
  // Other bad values and types.
  EXPECT_NE(ErrorOf("mocap:\n  latency_s: -0.1\n").find("latency_s"), std::string::npos);
  EXPECT_NE(ErrorOf("mocap:\n  dropout_probability: 1.0\n")
                .find("'mocap.dropout_probability': must be < 1"),
            std::string::npos);
  EXPECT_NE(ErrorOf("imu:\n  accel_noise: [0.1, -0.1, 0.1]\n").find("must be > 0"),
            std::string::npos);
  EXPECT_NE(ErrorOf("battery:\n  rate_hz: fast\n").find("expected a number"), std::string::npos);
  EXPECT_NE(ErrorOf("relative:\n  field_of_view: 0\n").find("field_of_view"), std::string::npos);
  // A disabled sensor may carry any rate.
  EXPECT_EQ(ErrorOf("battery:\n  enabled: false\n  rate_hz: 0\n"), "");
}

}  // namespace
}  // namespace fnmpc::config

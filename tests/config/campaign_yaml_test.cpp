// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/campaign_yaml.hpp"

#include <gtest/gtest.h>

#include <string>

namespace fnmpc::config {
namespace {

constexpr char kCampaign[] = R"(name: storm-drone-4
mass: 1.37
arm_length: 0.225
propeller_bench: bench.csv
pendulum:
  wire_separation: 0.30
  wire_length: 1.00
  runs: {x: pendulum_x.csv, y: pendulum_y.csv, z: pendulum_z.csv}
attitude_steps: attitude_steps.csv
flight: flight.csv
)";

std::string ErrorOf(const std::string& text) {
  try {
    ParseCampaign(YamlMap::LoadString(text, "campaign.yaml"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(CampaignYamlTest, ParsesTheDocumentedExample) {
  // Given the example of docs/data-formats.md, When parsed, Then every field is set.
  const Campaign c = ParseCampaign(YamlMap::LoadString(kCampaign, "campaign.yaml"));
  EXPECT_EQ(c.name, "storm-drone-4");
  EXPECT_DOUBLE_EQ(c.mass, 1.37);
  EXPECT_DOUBLE_EQ(c.wire_separation, 0.30);
  EXPECT_EQ(c.pendulum_y, "pendulum_y.csv");
  EXPECT_EQ(c.flight, "flight.csv");
}

TEST(CampaignYamlTest, FlightIsOptional) {
  std::string text = kCampaign;
  text.erase(text.find("flight:"));
  EXPECT_TRUE(ParseCampaign(YamlMap::LoadString(text, "c.yaml")).flight.empty());
}

TEST(CampaignYamlTest, ErrorsNameLineColumnAndKey) {
  // Given a negative mass, a misspelt key, a missing run and a syntax error,
  std::string neg = kCampaign;
  neg.replace(neg.find("1.37"), 4, "-1.0");
  std::string typo = kCampaign;
  typo.replace(typo.find("arm_length"), 10, "arm_lenght");
  std::string norun = kCampaign;
  norun.replace(norun.find(", z: pendulum_z.csv"), 19, "");
  // When parsed, Then the messages carry file:line:column and the key.
  EXPECT_NE(ErrorOf(neg).find("campaign.yaml:2:7: key 'mass': must be finite and > 0"),
            std::string::npos)
      << ErrorOf(neg);
  EXPECT_NE(ErrorOf(typo).find("arm_length"), std::string::npos) << ErrorOf(typo);
  EXPECT_NE(ErrorOf(norun).find("pendulum.runs.z"), std::string::npos) << ErrorOf(norun);
  EXPECT_NE(ErrorOf("mass: [1,\n").find("campaign.yaml:"), std::string::npos);
}

}  // namespace
}  // namespace fnmpc::config

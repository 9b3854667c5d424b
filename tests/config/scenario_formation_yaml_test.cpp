// SPDX-License-Identifier: BSD-3-Clause
// `formation:` generates the vehicles; the 10-vehicle wedge it generates is the
// hand-written one of config/scenarios/stress/wedge10-fast.yaml, and bad blocks name the key.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <sstream>
#include <string>

#include "fnmpc/config/scenario_yaml.hpp"

namespace fnmpc::config {
namespace {

const std::string kStress = std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/stress/";

std::string Read(const std::string& path) {
  std::ifstream f(path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// wedge10-fast.yaml with its `vehicles:` list replaced by `block`, written next to the
// original (same relative vehicle and sensors paths) under a unique name; removed after.
class FormationFile {
 public:
  explicit FormationFile(const std::string& block) {
    std::string text = Read(kStress + "wedge10-fast.yaml");
    const std::size_t begin = text.find("\nvehicles:\n");
    const std::size_t end = text.find("\nleader:\n");
    text.replace(begin + 1, end - begin, block);
    path_ = kStress + "formation-test-" + std::to_string(getpid()) + ".yaml";
    std::ofstream(path_) << text;
  }
  ~FormationFile() { std::remove(path_.c_str()); }
  FormationFile(const FormationFile&) = delete;
  FormationFile& operator=(const FormationFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

std::string ErrorOf(const std::string& block) {
  const FormationFile f(block);
  try {
    LoadScenarioFile(f.path());
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// The deep formations of config/scenarios/scale/ ship with the neighbours' plans (without them
// they are not string-stable, docs/results.md "Scale") and with reality on, like every other
// scenario a user flies by default.
TEST(ScenarioFormationYamlTest, ScaleScenariosFlyCooperativelyWithRealityOn) {
  for (const char* name : {"wedge28.yaml", "wedge28-fast.yaml", "grid100.yaml"}) {
    const ScenarioConfig s =
        LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/scale/" + name);
    EXPECT_TRUE(s.reality.enabled) << name;
    EXPECT_TRUE(s.reality.rotor_aerodynamics && s.reality.wake && s.reality.sensors) << name;
    EXPECT_EQ(s.compensation, formation::Compensation::kCooperative) << name;
  }
}

TEST(ScenarioFormationYamlTest, GeneratedWedgeIsTheHandWrittenOne) {
  const ScenarioConfig listed = LoadScenarioFile(kStress + "wedge10-fast.yaml");
  const FormationFile f(
      "formation: {shape: wedge, count: 10, spacing: 2.5, ties: 2, "
      "relative_position_bound: [6.0, 6.0, 2.0]}\n");
  const ScenarioConfig generated = LoadScenarioFile(f.path());
  ASSERT_EQ(generated.vehicles.size(), listed.vehicles.size());
  EXPECT_EQ(generated.leader, listed.leader);
  for (std::size_t i = 0; i < listed.vehicles.size(); ++i) {
    const ScenarioVehicle& a = listed.vehicles[i];
    const ScenarioVehicle& b = generated.vehicles[i];
    SCOPED_TRACE(a.name);
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.leader, a.leader);
    EXPECT_TRUE(b.start.isApprox(a.start)) << b.start.transpose();
    EXPECT_EQ(b.frame_control, a.frame_control);
    EXPECT_EQ(b.relative_position_bound, a.relative_position_bound);
    EXPECT_EQ(b.params.mass, a.params.mass);
    ASSERT_EQ(b.neighbours.size(), a.neighbours.size());
    for (std::size_t j = 0; j < a.neighbours.size(); ++j) {
      EXPECT_EQ(b.neighbours[j].vehicle, a.neighbours[j].vehicle);
      EXPECT_EQ(b.neighbours[j].index, a.neighbours[j].index);
      EXPECT_TRUE(b.neighbours[j].desired.isApprox(a.neighbours[j].desired));
    }
  }
}

TEST(ScenarioFormationYamlTest, LargeFormationsParse) {
  const FormationFile f("formation: {shape: grid, count: 100, spacing: 2.5, prefix: g}\n");
  const ScenarioConfig s = LoadScenarioFile(f.path());
  ASSERT_EQ(s.vehicles.size(), 100u);
  EXPECT_EQ(s.vehicles[99].name, "g99");
  EXPECT_EQ(s.vehicles[99].neighbours.size(), 2u);
}

TEST(ScenarioFormationYamlTest, BadBlocksNameFileLineAndKey) {
  const std::string both = ErrorOf(
      "formation: {shape: line, count: 3}\nvehicles:\n  - {name: a, role: leader, start: [0, "
      "0]}\n");
  EXPECT_NE(both.find("formation-test-"), std::string::npos) << both;
  EXPECT_NE(both.find(":11:"), std::string::npos) << both;
  EXPECT_NE(both.find("formation"), std::string::npos) << both;
  EXPECT_NE(both.find("not both"), std::string::npos) << both;
  const std::string shape = ErrorOf("formation: {shape: square, count: 3}\n");
  EXPECT_NE(shape.find("formation.shape"), std::string::npos) << shape;
  EXPECT_NE(shape.find("square"), std::string::npos) << shape;
  EXPECT_NE(ErrorOf("formation: {shape: line, count: 1}\n").find("formation.count"),
            std::string::npos);
  EXPECT_NE(ErrorOf("formation: {shape: line, count: 129}\n").find("formation.count"),
            std::string::npos);
  EXPECT_NE(ErrorOf("formation: {shape: line, count: 4, ties: 9}\n").find("formation.ties"),
            std::string::npos);
  EXPECT_NE(ErrorOf("formation: {shape: line, count: 4, spacing: 0.5}\n").find("formation.spacing"),
            std::string::npos);
  EXPECT_NE(ErrorOf("formation: {shape: wedge, count: 4, columns: 2}\n").find("formation.columns"),
            std::string::npos);
  EXPECT_NE(ErrorOf("formation: {shape: line, count: 4, colour: red}\n").find("colour"),
            std::string::npos);
}

TEST(ScenarioFormationYamlTest, ALeaderAloneIsAScenarioAndNoVehicleIsAnError) {
  const ScenarioConfig single =
      LoadScenarioFile(std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/single.yaml");
  ASSERT_EQ(single.vehicles.size(), 1u);
  EXPECT_TRUE(single.vehicles[0].leader);
  const std::string none = ErrorOf("vehicles: []\n");
  EXPECT_NE(none.find("vehicles"), std::string::npos) << none;
  EXPECT_NE(none.find("at least one vehicle"), std::string::npos) << none;
}

TEST(ScenarioFormationYamlTest, TiesBeyondTheSensorRangeAreWarnings) {
  // 9 m rows: beyond the default relative sensor's 8 m range.
  const FormationFile f("formation: {shape: line, count: 3, spacing: 9.0}\n");
  const ScenarioConfig s = LoadScenarioFile(f.path());
  ASSERT_FALSE(s.warnings.empty());
  EXPECT_NE(s.warnings.front().find("beyond the relative sensor's range"), std::string::npos)
      << s.warnings.front();
}

TEST(ScenarioFormationYamlTest, DesiredOffsetsOutsideTheRelativeBoundAreWarnings) {
  // A 12-vehicle circle (radius 4.4 m) with 8 ties: ties across it, beyond the 6 m bound.
  const FormationFile f("formation: {shape: circle, count: 12, spacing: 2.5, ties: 8}\n");
  const ScenarioConfig s = LoadScenarioFile(f.path());
  std::string all;
  for (const auto& w : s.warnings) all += w + "\n";
  EXPECT_NE(all.find("formation.ties"), std::string::npos) << all;
  EXPECT_NE(all.find("lies outside its relative_position_bound (6, 6, 2) m"), std::string::npos)
      << all;
  // With 2 ties every offset fits the bound: no such warning.
  const FormationFile two("formation: {shape: circle, count: 12, spacing: 2.5, ties: 2}\n");
  for (const auto& w : LoadScenarioFile(two.path()).warnings) {
    EXPECT_EQ(w.find("relative_position_bound"), std::string::npos) << w;
  }
}

}  // namespace
}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
// One definition of each setting (issue #16): docs/scenarios.md's settings table and the
// settings structs' Serialize cannot drift apart, and every key they define is read from YAML.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/config/settings_doc.hpp"
#include "scenario_text.hpp"

namespace fnmpc::config {
namespace {

const std::string kDocPath = std::string(FNMPC_SOURCE_DIR) + "/docs/scenarios.md";

std::string ReadText(const std::string& path) {
  std::ifstream f(path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

bool Has(const std::vector<std::string>& v, const std::string& line) {
  return std::find(v.begin(), v.end(), line) != v.end();
}

// The shipped reference: no key documented that is not defined, none defined that is not
// documented, and every row as generated. FNMPC_WRITE_SETTINGS_DOC=1 rewrites the table.
TEST(ScenarioSettingsDocTest, DocsScenariosMdMatchesTheDefinitions) {
  const std::string md = ReadText(kDocPath);
  ASSERT_FALSE(md.empty()) << kDocPath;
  const std::vector<SettingDoc> defined = ScenarioSettingsDocs();
  const std::vector<std::string> drift = SettingsDocDrift(md, defined);
  if (!drift.empty() && std::getenv("FNMPC_WRITE_SETTINGS_DOC") != nullptr) {
    std::ofstream(kDocPath) << WithSettingsTable(md, defined);
  }
  std::string all;
  for (const std::string& d : drift) all += d + "\n";
  EXPECT_TRUE(drift.empty()) << all << "expected table:\n"
                             << SettingsTable(defined)
                             << "(FNMPC_WRITE_SETTINGS_DOC=1 ctest -R ScenarioSettingsDoc "
                                "rewrites it)";
}

// The check fails both ways: a documented key that no struct defines, a defined key that the
// table lacks, and a changed default.
TEST(ScenarioSettingsDocTest, DriftIsReportedBothWays) {
  const std::vector<SettingDoc> defined = ScenarioSettingsDocs();
  const std::string begin = std::string(kSettingsBegin) + "\n";
  const std::string good =
      "intro\n" + begin + SettingsTable(defined) + std::string(kSettingsEnd) + "\nrest\n";
  EXPECT_TRUE(SettingsDocDrift(good, defined).empty());

  std::string bad = good;
  const std::size_t row = bad.find("| `controller.horizon` |");
  ASSERT_NE(row, std::string::npos);
  bad.erase(row, bad.find('\n', row) + 1 - row);
  bad.insert(row, "| `controller.horizon_length` | 15 | 1..100 | N |\n");
  const std::vector<std::string> drift = SettingsDocDrift(bad, defined);
  EXPECT_TRUE(Has(drift, "documented but not defined: controller.horizon_length"));
  EXPECT_TRUE(Has(drift, "defined but not documented: controller.horizon"));
  EXPECT_EQ(drift.size(), 2u);

  std::string changed = good;
  const std::string old_row = "| `phases.climb_speed` | 0.5 |";
  ASSERT_NE(changed.find(old_row), std::string::npos);
  changed.replace(changed.find(old_row), old_row.size(), "| `phases.climb_speed` | 0.7 |");
  ASSERT_EQ(SettingsDocDrift(changed, defined).size(), 1u);
  EXPECT_NE(SettingsDocDrift(changed, defined)[0].find("differs"), std::string::npos);

  EXPECT_TRUE(
      Has(SettingsDocDrift("no table here", defined), "the settings table markers are missing"));
}

// Every defined key is read by the parser: the shipped triangle with each key set to its
// documented default parses (an unknown key would be an error) to the same settings.
TEST(ScenarioSettingsDocTest, EveryDefinedKeyIsReadFromYaml) {
  YAML::Node root = YAML::Load(test::ShippedScenarioText("triangle.yaml"));
  const std::vector<SettingDoc> defined = ScenarioSettingsDocs();
  for (const SettingDoc& f : defined) {
    std::vector<std::string> path;
    std::stringstream ks(f.key);
    for (std::string part; std::getline(ks, part, '.');) path.push_back(part);
    YAML::Node n = root;
    for (std::size_t k = 0; k + 1 < path.size(); ++k) {
      if (!n[path[k]]) n[path[k]] = YAML::Node(YAML::NodeType::Map);
      n.reset(n[path[k]]);
    }
    n[path.back()] = YAML::Load(f.default_value);
  }
  // cpu_budget defaults to the sample time; the weight-dependent thrust bounds and the
  // scenario's own landing time are the file's.
  root["controller"]["bounds"]["thrust"] = YAML::Load("[5, 25]");
  root["phases"]["landing_time"] = YAML::Load("50");
  root["leader"]["start_time"] = YAML::Load("12");
  std::stringstream out;
  out << root;
  const ScenarioConfig s = ParseScenario(YamlMap::LoadString(out.str(), "all-keys.yaml"));
  EXPECT_EQ(s.rti.horizon, 15);
  EXPECT_EQ(s.rti.qp.max_iterations, 500);
  EXPECT_TRUE(s.rti.unconstrained_shortcut);
  EXPECT_DOUBLE_EQ(s.follower_weights.collision, 1000.0);
}

// The settings the scenario could not set before issue #16: QP settings, soft-bound weights
// and the unconstrained shortcut; their errors name the key.
TEST(ScenarioSettingsDocTest, QpSoftBoundsAndShortcutAreSettable) {
  std::string text = test::ShippedScenarioText("triangle.yaml");
  auto with = [&text](const std::string& controller) {
    YAML::Node root = YAML::Load(text);
    YAML::Node c = YAML::Load(controller);
    for (auto it = c.begin(); it != c.end(); ++it) root["controller"][it->first] = it->second;
    std::stringstream out;
    out << root;
    return ParseScenario(YamlMap::LoadString(out.str(), "s.yaml"));
  };
  const ScenarioConfig s = with(
      "{qp: {max_iterations: 50, tolerance: 1e-9, warm_start: false, warm_start_batch: false}, "
      "soft_linear_weight: 2e3, soft_quadratic_weight: 50, unconstrained_shortcut: false}");
  EXPECT_EQ(s.rti.qp.max_iterations, 50);
  EXPECT_DOUBLE_EQ(s.rti.qp.tolerance, 1e-9);
  EXPECT_FALSE(s.rti.qp.warm_start);
  EXPECT_FALSE(s.rti.qp.warm_start_batch);
  EXPECT_DOUBLE_EQ(s.rti.soft_linear_weight, 2e3);
  EXPECT_DOUBLE_EQ(s.rti.soft_quadratic_weight, 50.0);
  EXPECT_FALSE(s.rti.unconstrained_shortcut);
  try {
    with("{qp: {tolerance: -1}}");
    FAIL() << "a negative QP tolerance was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("s.yaml:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("key 'controller.qp.tolerance': must be > 0"),
              std::string::npos)
        << e.what();
  }
  try {
    with("{qp: {max_iteration: 5}}");
    FAIL() << "a misspelt key was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("controller.qp.max_iteration"), std::string::npos)
        << e.what();
  }
}

// controller.compensation (issue #17): a name of the list; the planned levels are refused as
// not implemented yet, with the file, line and key.
TEST(ScenarioSettingsDocTest, CompensationAcceptsImplementedLevelsOnly) {
  const std::string text = test::ShippedScenarioText("triangle.yaml");
  auto with = [&text](const std::string& level) {
    YAML::Node root = YAML::Load(text);
    root["controller"]["compensation"] = level;
    std::stringstream out;
    out << root;
    return ParseScenario(YamlMap::LoadString(out.str(), "s.yaml"));
  };
  EXPECT_EQ(ParseScenario(YamlMap::LoadString(text, "t.yaml")).compensation,
            formation::Compensation::kNone);
  EXPECT_EQ(with("observer").compensation, formation::Compensation::kObserver);
  EXPECT_EQ(with("none").compensation, formation::Compensation::kNone);
  for (const std::string level : {"wake", "cooperative", "Observer"}) {
    try {
      with(level);
      FAIL() << level << " was accepted";
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("s.yaml:"), std::string::npos) << what;
      EXPECT_NE(what.find("key 'controller.compensation'"), std::string::npos) << what;
      EXPECT_NE(what.find(level == "Observer" ? "must be one of none, observer"
                                              : "is not implemented yet"),
                std::string::npos)
          << what;
    }
  }
}

}  // namespace
}  // namespace fnmpc::config

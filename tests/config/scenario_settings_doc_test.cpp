// SPDX-License-Identifier: BSD-3-Clause
// One definition of each setting: docs/scenarios.md's settings table and the
// settings structs' Serialize cannot drift apart, and every key they define is read from YAML.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/config/sensors_yaml.hpp"
#include "fnmpc/config/settings_doc.hpp"
#include "fnmpc/config/text_file.hpp"
#include "fnmpc/rti/rti_settings.hpp"
#include "scenario_text.hpp"

namespace fnmpc::config {
namespace {

const std::string kDocPath = std::string(FNMPC_SOURCE_DIR) + "/docs/scenarios.md";

bool Has(const std::vector<std::string>& v, const std::string& line) {
  return std::find(v.begin(), v.end(), line) != v.end();
}

/// Sets every key of `fields` (dotted) in `root` to its documented default, except the keys
/// `skip` accepts.
template <class Skip>
void SetDefaults(const std::vector<SettingDoc>& fields, const Skip& skip, YAML::Node root) {
  for (const SettingDoc& f : fields) {
    if (skip(f)) continue;
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
}

/// For each generated table of the markdown file `path`: no key documented that is not
/// defined, none defined that is not documented, and every row as generated.
/// FNMPC_WRITE_SETTINGS_DOC=1 rewrites the tables.
void ExpectTablesMatch(const std::string& path,
                       const std::vector<std::pair<std::string, std::vector<SettingDoc>>>& tables) {
  std::string md = ReadTextFile(path);
  ASSERT_FALSE(md.empty()) << path;
  for (const auto& [table, defined] : tables) {
    const std::vector<std::string> drift = SettingsDocDrift(md, defined, table);
    if (!drift.empty() && std::getenv("FNMPC_WRITE_SETTINGS_DOC") != nullptr) {
      md = WithSettingsTable(md, defined, table);
      std::ofstream(path) << md;
    }
    std::string all;
    for (const std::string& d : drift) all += d + "\n";
    EXPECT_TRUE(drift.empty()) << path << ": " << all << "expected " << table << " table:\n"
                               << SettingsTable(defined)
                               << "(FNMPC_WRITE_SETTINGS_DOC=1 ctest -R ScenarioSettingsDoc "
                                  "rewrites it)";
  }
}

// The shipped reference: the scenario's settings, the `reality:` block, the sensors file.
TEST(ScenarioSettingsDocTest, DocsScenariosMdMatchesTheDefinitions) {
  ExpectTablesMatch(kDocPath, {{"settings", ScenarioSettingsDocs()},
                               {"reality", RealitySettingsDocs()},
                               {"sensors file", SensorsSettingsDocs()}});
}

// docs/rti.md's table of the solver's own settings (rti::RtiSettings with its qp::QpSettings).
TEST(ScenarioSettingsDocTest, DocsRtiMdMatchesRtiSettings) {
  rti::RtiSettings defaults;
  SettingsDocWriter writer;
  writer.Read(&defaults);
  ASSERT_FALSE(writer.fields().empty());
  ExpectTablesMatch(std::string(FNMPC_SOURCE_DIR) + "/docs/rti.md",
                    {{"rti settings", writer.fields()}});
}

// The check fails both ways: a documented key that no struct defines, a defined key that the
// table lacks, and a changed default.
TEST(ScenarioSettingsDocTest, DriftIsReportedBothWays) {
  const std::vector<SettingDoc> defined = ScenarioSettingsDocs();
  const std::string begin = TableBegin("settings") + "\n";
  const std::string good =
      "intro\n" + begin + SettingsTable(defined) + TableEnd("settings") + "\nrest\n";
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
  SetDefaults(
      ScenarioSettingsDocs(), [](const SettingDoc&) { return false; }, root);
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

// Every key of the `reality:` table is read: each set to its documented default parses to
// the defaults (the turbulence block's two forms exclude each other: checked one by one).
TEST(ScenarioSettingsDocTest, EveryRealityKeyIsReadFromYaml) {
  YAML::Node root = YAML::Load(test::ShippedScenarioText("triangle.yaml"));
  root["reality"] = YAML::Node(YAML::NodeType::Map);
  SetDefaults(
      RealitySettingsDocs(),
      [](const SettingDoc& f) {
        return f.default_value == "none" || f.key.find("[]") != std::string::npos ||
               f.key.rfind("reality.wind.turbulence.", 0) == 0;
      },
      root);
  std::stringstream out;
  out << root;
  const ScenarioReality r = ParseScenario(YamlMap::LoadString(out.str(), "r.yaml")).reality;
  const ScenarioReality d;
  EXPECT_FALSE(r.enabled);  // its documented default, given explicitly
  EXPECT_TRUE(r.rotor_aerodynamics && r.wake && r.sensors);
  EXPECT_EQ(r.sensor_models.gyro_bias_walk, d.sensor_models.gyro_bias_walk);
  EXPECT_EQ(r.sensor_models.estimate_time_constant, d.sensor_models.estimate_time_constant);
  EXPECT_EQ(r.plant.voltage_dependence, d.plant.voltage_dependence);
  EXPECT_NEAR(r.plant.attitude_bias_max, d.plant.attitude_bias_max, 1e-15);
  EXPECT_EQ(r.wind.gust_time_constant, d.wind.gust_time_constant);
  EXPECT_EQ(r.wind.velocity, d.wind.velocity);

  for (const char* turbulence : {"{w20: 3, height: 20, airspeed: 2}",
                                 "{sigma: [1, 1, 0.5], length_scale: [100, 100, 20], "
                                 "airspeed: 2}"}) {
    root["reality"]["wind"]["turbulence"] = YAML::Load(turbulence);
    std::stringstream t;
    t << root;
    const ScenarioTurbulence b =
        ParseScenario(YamlMap::LoadString(t.str(), "t.yaml")).reality.turbulence;
    EXPECT_TRUE(b.enabled()) << turbulence;
    EXPECT_EQ(b.airspeed, 2.0);
    EXPECT_TRUE(std::isfinite(b.w20) ? b.height == 20.0 : b.length_scale.z() == 20.0);
  }
}

// Every key of the sensors-file table is read: each set to its documented default parses to
// SensorsConfig's defaults (the table prints 6 digits).
TEST(ScenarioSettingsDocTest, EverySensorsKeyIsReadFromYaml) {
  YAML::Node root(YAML::NodeType::Map);
  SetDefaults(
      SensorsSettingsDocs(), [](const SettingDoc&) { return false; }, root);
  std::stringstream out;
  out << root;
  const SensorsConfig c = ParseSensors(YamlMap::LoadString(out.str(), "s.yaml"));
  const SensorsConfig d;
  for (auto [a, b] :
       {std::pair{&c.mocap, &d.mocap}, std::pair{&c.imu, &d.imu},
        std::pair{&c.optical_flow, &d.optical_flow}, std::pair{&c.compass, &d.compass},
        std::pair{&c.battery, &d.battery}, std::pair{&c.relative, &d.relative}}) {
    EXPECT_EQ(a->enabled, b->enabled);
    EXPECT_EQ(a->rate_hz, b->rate_hz);
    EXPECT_EQ(a->latency_s, b->latency_s);
    EXPECT_TRUE(a->noise.isApprox(b->noise, 1e-6));
    EXPECT_TRUE(a->noise2.isApprox(b->noise2, 1e-6) || b->noise2.isZero());
  }
  EXPECT_NEAR(c.relative.field_of_view, d.relative.field_of_view, 1e-5);
  EXPECT_EQ(c.relative.max_range, d.relative.max_range);
  EXPECT_EQ(c.relative.range_noise_growth, d.relative.range_noise_growth);
  // A misspelt sensor key is still an error naming it.
  EXPECT_THROW(ParseSensors(YamlMap::LoadString("imu: {accel_nosie: 1}\n", "s.yaml")), ConfigError);
}

// The QP settings, soft-bound weights and the unconstrained shortcut are settable from the
// scenario; their errors name the key.
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

// controller.compensation: a name of the list; any other name (a wrong case too) is refused
// with the file, line and key.
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
  EXPECT_EQ(with("wake").compensation, formation::Compensation::kWake);
  EXPECT_EQ(with("cooperative").compensation, formation::Compensation::kCooperative);
  for (const std::string level : {"Observer"}) {
    try {
      with(level);
      FAIL() << level << " was accepted";
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("s.yaml:"), std::string::npos) << what;
      EXPECT_NE(what.find("key 'controller.compensation'"), std::string::npos) << what;
      EXPECT_NE(what.find("must be one of none, observer, wake, cooperative"), std::string::npos)
          << what;
    }
  }
}

}  // namespace
}  // namespace fnmpc::config

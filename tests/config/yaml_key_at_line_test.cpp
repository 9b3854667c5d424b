// SPDX-License-Identifier: BSD-3-Clause
// The key region of a line of YAML text (syntax and structure errors name a key: docs/failure.md).
#include "fnmpc/config/yaml_key_at_line.hpp"

#include <gtest/gtest.h>

#include <string>

#include "fnmpc/config/yaml_reader.hpp"

namespace fnmpc::config {
namespace {

const std::string kScenario =
    "name: t\n"                                        // 1
    "vehicles:\n"                                      // 2
    "  - name: leader\n"                               // 3
    "    vehicle_file: v.yaml\n"                       // 4
    "  - name: follower\n"                             // 5
    "    neighbours:\n"                                // 6
    "      - {vehicle: leader, desired: [1, 2, 0]}\n"  // 7
    "      - {vehicle: other,\n"                       // 8
    "         desired: [0, 1, 0]}\n"                   // 9
    "\n"                                               // 10
    "controller:\n"                                    // 11
    "  horizon: 20   # steps\n"                        // 12
    "  # a comment\n"                                  // 13
    "leader:\n"                                        // 14
    "  waypoints:\n"                                   // 15
    "  - [1, 0, 0]\n"                                  // 16
    "  - [2, 0, 0]\n"                                  // 17
    "  sample_time: 0.02\n"                            // 18
    "garbage at the top\n";                            // 19

TEST(YamlKeyAtLineTest, NamesTheKeyOfTheLineOrTheRegionItFallsIn) {
  EXPECT_EQ(YamlKeyAtLine(kScenario, 1), "name");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 2), "vehicles");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 3), "vehicles[0].name");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 4), "vehicles[0].vehicle_file");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 5), "vehicles[1].name");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 6), "vehicles[1].neighbours");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 7), "vehicles[1].neighbours[0]");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 8), "vehicles[1].neighbours[1]");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 9), "vehicles[1].neighbours[1]");   // continuation
  EXPECT_EQ(YamlKeyAtLine(kScenario, 10), "vehicles[1].neighbours[1]");  // blank: the node above
  EXPECT_EQ(YamlKeyAtLine(kScenario, 12), "controller.horizon");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 13), "controller.horizon");   // comment
  EXPECT_EQ(YamlKeyAtLine(kScenario, 16), "leader.waypoints[0]");  // compact sequence
  EXPECT_EQ(YamlKeyAtLine(kScenario, 17), "leader.waypoints[1]");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 18), "leader.sample_time");
  EXPECT_EQ(YamlKeyAtLine(kScenario, 19), kTopLevelKey);  // a line in no key
  // Past the end: the last line, blank after the final newline, so the node above it.
  EXPECT_EQ(YamlKeyAtLine(kScenario, 400), "leader.sample_time");
  EXPECT_EQ(YamlKeyAtLine("", 1), kTopLevelKey);
  EXPECT_EQ(YamlKeyAtLine("[1, 2", 1), kTopLevelKey);
  EXPECT_EQ(YamlKeyAtLine("a:\r\n  b: 1\r\n", 2), "a.b");
  EXPECT_EQ(YamlKeyAtLine("- a: 1\n  b: 2\n- c: 3\n", 3), "[1].c");  // a top-level list
  // 2000 nested keys (far deeper than the parser's 64 levels; 2 MB of indentation).
  std::string deep;
  for (int k = 0; k < 2000; ++k) deep += std::string(static_cast<std::size_t>(k), ' ') + "k:\n";
  EXPECT_EQ(YamlKeyAtLine(deep, 2000).size(), 2000u * 2 - 1);  // "k.k. ... .k"
}

std::string LoadError(const std::string& text) {
  try {
    YamlMap::LoadString(text, "x.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(YamlKeyAtLineTest, DocumentErrorsCarryFileLineAndKey) {
  // A syntax error inside the controller block.
  ErrorPlace p = ParseErrorPlace(LoadError("name: a\ncontroller:\n  horizon: [1, 2\n"));
  EXPECT_TRUE(p.placed);
  EXPECT_EQ(p.file, "x.yaml");
  EXPECT_GT(p.line, 0);
  EXPECT_EQ(p.key.rfind("controller", 0), 0u) << p.what;
  EXPECT_NE(p.what.find("YAML syntax error"), std::string::npos) << p.what;
  // A top level that is not a mapping, and an empty document.
  p = ParseErrorPlace(LoadError("- 1\n- 2\n"));
  EXPECT_TRUE(p.placed);
  EXPECT_EQ(p.key, kTopLevelKey);
  EXPECT_NE(p.what.find("expected a mapping at the top level"), std::string::npos) << p.what;
  p = ParseErrorPlace(LoadError(""));
  EXPECT_TRUE(p.placed);
  EXPECT_EQ(p.line, 1);
  EXPECT_EQ(p.key, kTopLevelKey);
  // An invalid byte inside a key's value.
  p = ParseErrorPlace(LoadError("name: a\nmass: 1.3\xff\n"));
  EXPECT_TRUE(p.placed);
  EXPECT_EQ(p.line, 2);
  EXPECT_EQ(p.key, "mass");
  EXPECT_NE(p.what.find("invalid UTF-8"), std::string::npos) << p.what;
}

}  // namespace
}  // namespace fnmpc::config

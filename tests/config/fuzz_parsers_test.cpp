// SPDX-License-Identifier: BSD-3-Clause
// Seeded mutation fuzzing of every file parser (docs/failure.md): vehicle, sensors, scenario and
// campaign YAML, the sysid and calibrate CSVs. Each valid seed file is mutated a fixed number
// of times (byte flips, deletions, duplications, hostile tokens); every mutant must parse or
// be rejected with a ConfigError that names the file, the line and the key (YAML; errors about
// the document's structure name the key whose region they fall in, or "(top level)") or the
// column (CSV): 100 % of rejections, or the test fails. Crashes fail the test
// (and ASan/UBSan in CI); hangs hit the ctest timeout. Budget: FNMPC_FUZZ_ITERATIONS mutants
// per parser (default 400).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "fnmpc/config/campaign_yaml.hpp"
#include "fnmpc/config/csv_reader.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/config/sensors_yaml.hpp"
#include "fnmpc/config/text_file.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "scenario_text.hpp"

namespace fnmpc::config {
namespace {

int Iterations() {
  const char* env = std::getenv("FNMPC_FUZZ_ITERATIONS");
  return env != nullptr ? std::max(1, std::atoi(env)) : 400;
}

/// One random edit of `text`.
std::string Mutate(std::string text, std::mt19937_64& rng) {
  static const std::vector<std::string> kTokens = {".nan",
                                                   ".inf",
                                                   "-.inf",
                                                   "1e309",
                                                   "-1e308",
                                                   "0",
                                                   "-0",
                                                   "1e-320",
                                                   "99999999999999999999",
                                                   "~",
                                                   "null",
                                                   "[",
                                                   "]",
                                                   "{",
                                                   "}",
                                                   ":",
                                                   ": ",
                                                   ",",
                                                   "- ",
                                                   "\n",
                                                   "\t",
                                                   "'",
                                                   "\"",
                                                   "#",
                                                   "&a ",
                                                   "*a",
                                                   "!!binary ",
                                                   "\xff",
                                                   "\xc0\xaf",
                                                   "\xe2\x82",
                                                   "\x00",
                                                   "mass: 2\n",
                                                   "x: [1, 2]\n",
                                                   "name: ../../x\n",
                                                   "true",
                                                   "1,2,3",
                                                   ",,,",
                                                   "nan",
                                                   "inf",
                                                   "1e17"};
  auto pos = [&](std::size_t n) {
    return n == 0 ? 0 : std::uniform_int_distribution<std::size_t>(0, n)(rng);
  };
  const int kind = std::uniform_int_distribution<int>(0, 6)(rng);
  switch (kind) {
    case 0: {  // flip a byte
      if (text.empty()) break;
      const std::size_t p = pos(text.size() - 1);
      text[p] = static_cast<char>(text[p] ^ (1 << std::uniform_int_distribution<int>(0, 7)(rng)));
      break;
    }
    case 1: {  // delete a range
      const std::size_t p = pos(text.size());
      text.erase(p, std::uniform_int_distribution<std::size_t>(1, 40)(rng));
      break;
    }
    case 2: {  // insert a hostile token
      const auto& tok =
          kTokens[std::uniform_int_distribution<std::size_t>(0, kTokens.size() - 1)(rng)];
      text.insert(pos(text.size()), tok);
      break;
    }
    case 3: {  // duplicate a line
      const std::size_t p = text.find('\n', pos(text.size()));
      if (p == std::string::npos) break;
      const std::size_t b = text.rfind('\n', p == 0 ? 0 : p - 1);
      const std::size_t start = b == std::string::npos ? 0 : b + 1;
      text.insert(p + 1, text.substr(start, p - start + 1));
      break;
    }
    case 4: {  // replace a number by a token
      const std::size_t p = text.find_first_of("0123456789", pos(text.size()));
      if (p == std::string::npos) break;
      const std::size_t e = text.find_first_not_of("0123456789.e-+", p);
      text.replace(p, (e == std::string::npos ? text.size() : e) - p,
                   kTokens[std::uniform_int_distribution<std::size_t>(0, 9)(rng)]);
      break;
    }
    case 5:  // truncate
      text.resize(pos(text.size()));
      break;
    default: {  // change indentation of a line
      const std::size_t p = text.find('\n', pos(text.size()));
      if (p != std::string::npos)
        text.insert(p + 1, std::uniform_int_distribution<int>(0, 1)(rng) ? "  " : " ");
      break;
    }
  }
  return text;
}

struct Outcome {
  int parsed = 0, rejected = 0, placed = 0;
  std::vector<std::string> unplaced;  // rejections without file, line and key
};

/// True when `message` has the form "name:line:column: ... key 'k' ..." (or column 'k' for
/// CSV files) with a non-empty key, as config::ParseErrorPlace reads it.
bool NamesFileLineAndKey(const std::string& message, const std::string& name,
                         const std::string& key_word) {
  const ErrorPlace place = ParseErrorPlace(message);
  if (!place.placed || place.file != name || place.line < 1) return false;
  const std::size_t k = place.what.find(key_word + " '");
  if (k == std::string::npos) return false;
  const std::size_t begin = k + key_word.size() + 2;
  const std::size_t end = place.what.find('\'', begin);
  return end != std::string::npos && end > begin;
}

/// Runs `parse` on `iterations` mutants of `seed` (1 to 3 edits each).
Outcome Fuzz(const std::string& seed, const std::string& name, std::uint64_t rng_seed,
             const std::string& key_word, const std::function<void(const std::string&)>& parse) {
  std::mt19937_64 rng(rng_seed);
  Outcome o;
  for (int i = 0; i < Iterations(); ++i) {
    std::string text = seed;
    const int edits = std::uniform_int_distribution<int>(1, 3)(rng);
    for (int k = 0; k < edits; ++k) text = Mutate(text, rng);
    try {
      parse(text);
      ++o.parsed;
    } catch (const ConfigError& e) {
      ++o.rejected;
      if (NamesFileLineAndKey(e.what(), name, key_word)) {
        ++o.placed;
      } else {
        o.unplaced.push_back(e.what());
      }
    } catch (const std::exception& e) {
      ++o.rejected;
      o.unplaced.push_back(std::string("not a ConfigError: ") + e.what());
    }
  }
  return o;
}

void Expect(const Outcome& o, const std::string& parser) {
  std::string examples;
  for (std::size_t k = 0; k < o.unplaced.size() && k < 5; ++k) examples += o.unplaced[k] + "\n";
  EXPECT_TRUE(o.unplaced.empty()) << parser << ": " << o.unplaced.size() << " of " << o.rejected
                                  << " rejections without file, line and key, e.g.\n"
                                  << examples;
  EXPECT_EQ(o.placed, o.rejected);
  EXPECT_GT(o.rejected, 0) << parser << ": the mutations never broke the file";
  std::printf("fuzz %s: %d mutants, %d parsed, %d rejected, %d (%.1f %%) with file, line and key\n",
              parser.c_str(), o.parsed + o.rejected, o.parsed, o.rejected, o.placed,
              o.rejected > 0 ? 100.0 * o.placed / o.rejected : 0.0);
}

const std::string kRoot = std::string(FNMPC_SOURCE_DIR) + "/config/";

// The check itself can fail: messages that lack the file, the line or the key are not counted.
TEST(FuzzParsersTest, CheckerRefusesMessagesWithoutFileLineOrKey) {
  EXPECT_TRUE(NamesFileLineAndKey("v.yaml:3:7: key 'mass': expected a number", "v.yaml", "key"));
  EXPECT_TRUE(NamesFileLineAndKey("a.csv:2:1: column 't': no data rows", "a.csv", "column"));
  EXPECT_FALSE(
      NamesFileLineAndKey("v.yaml:3:7: YAML syntax error: end of map not found", "v.yaml", "key"));
  EXPECT_FALSE(NamesFileLineAndKey("v.yaml: key 'mass': expected a number", "v.yaml", "key"));
  EXPECT_FALSE(NamesFileLineAndKey("w.yaml:3:7: key 'mass': expected a number", "v.yaml", "key"));
  EXPECT_FALSE(NamesFileLineAndKey("v.yaml:3:7: key '': expected a number", "v.yaml", "key"));
  EXPECT_FALSE(NamesFileLineAndKey("[VehicleParams] mass must be positive", "v.yaml", "key"));
}

TEST(FuzzParsersTest, VehicleYaml) {
  const std::string seed = ReadTextFile(kRoot + "vehicles/storm-drone-4.yaml");
  Expect(Fuzz(seed, "v.yaml", 11, "key",
              [](const std::string& t) { ParseVehicle(YamlMap::LoadString(t, "v.yaml")); }),
         "vehicle");
}

TEST(FuzzParsersTest, SensorsYaml) {
  const std::string seed = ReadTextFile(kRoot + "sensors/default.yaml");
  Expect(Fuzz(seed, "s.yaml", 12, "key",
              [](const std::string& t) { ParseSensors(YamlMap::LoadString(t, "s.yaml")); }),
         "sensors");
}

TEST(FuzzParsersTest, ScenarioYaml) {
  for (const std::string file : {"triangle.yaml", "manual-leader.yaml"}) {
    const std::string seed = test::ShippedScenarioText(file);
    Expect(Fuzz(seed, "x.yaml", 13, "key",
                [](const std::string& t) { ParseScenario(YamlMap::LoadString(t, "x.yaml")); }),
           "scenario " + file);
  }
}

TEST(FuzzParsersTest, CampaignYaml) {
  const std::string seed =
      "name: synthetic-storm-drone\nmass: 1.37\narm_length: 0.225\npropeller_bench: bench.csv\n"
      "pendulum:\n  wire_separation: 0.3\n  wire_length: 1.2\n"
      "  runs: {x: pendulum_x.csv, y: pendulum_y.csv, z: pendulum_z.csv}\n"
      "attitude_steps: attitude_steps.csv\nflight: flight.csv\n";
  Expect(Fuzz(seed, "c.yaml", 14, "key",
              [](const std::string& t) { ParseCampaign(YamlMap::LoadString(t, "c.yaml")); }),
         "campaign");
}

TEST(FuzzParsersTest, SysidAndCalibrateCsv) {
  std::string steps = "t,roll_ref,pitch_ref,yaw_ref,roll,pitch,yaw\n";
  std::string flight =
      "t,x,y,z,vx,vy,vz,roll,pitch,yaw,thrust_cmd,roll_cmd,pitch_cmd,yaw_cmd,voltage\n";
  for (int k = 0; k < 40; ++k) {
    const double t = 0.01 * k;
    steps += std::to_string(t) + ",0.1,0,0.2,0.09,0.001,3.1\n";
    flight += std::to_string(t) + ",0,0,1,0,0,0,0.01,0,3.14,13.4,0,0,0,16.1\n";
  }
  Expect(Fuzz(steps, "a.csv", 15, "column",
              [](const std::string& t) {
                ParseCsv(t, "a.csv",
                         {"t", "roll_ref", "pitch_ref", "yaw_ref", "roll", "pitch", "yaw"}, "t");
              }),
         "attitude_steps.csv");
  Expect(Fuzz(flight, "f.csv", 16, "column",
              [](const std::string& t) {
                ParseCsv(t, "f.csv",
                         {"t", "x", "y", "z", "vx", "vy", "vz", "roll", "pitch", "yaw",
                          "thrust_cmd", "roll_cmd", "pitch_cmd", "yaw_cmd", "voltage"},
                         "t");
              }),
         "flight.csv");
}

}  // namespace
}  // namespace fnmpc::config

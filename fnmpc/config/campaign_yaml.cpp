// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/campaign_yaml.hpp"

#include <cmath>
#include <filesystem>

namespace fnmpc::config {
namespace {

double Positive(YamlMap& map, const std::string& key) {
  const double v = map.Double(key);
  if (!(v > 0.0) || !std::isfinite(v)) {
    throw map.ErrorAt(key, "must be finite and > 0, got " + std::to_string(v));
  }
  return v;
}

std::string PathOf(YamlMap& map, const std::string& key) {
  const std::string p = map.String(key);
  if (p.empty()) throw map.ErrorAt(key, "empty path");
  const std::filesystem::path fp(p);
  if (fp.is_absolute() || map.directory().empty()) return p;
  return (std::filesystem::path(map.directory()) / fp).string();
}

}  // namespace

Campaign ParseCampaign(YamlMap map) {
  Campaign c;
  c.name = map.String("name");
  c.mass = Positive(map, "mass");
  c.arm_length = Positive(map, "arm_length");
  c.propeller_bench = PathOf(map, "propeller_bench");
  YamlMap pend = map.Map("pendulum");
  c.wire_separation = Positive(pend, "wire_separation");
  c.wire_length = Positive(pend, "wire_length");
  YamlMap runs = pend.Map("runs");
  c.pendulum_x = PathOf(runs, "x");
  c.pendulum_y = PathOf(runs, "y");
  c.pendulum_z = PathOf(runs, "z");
  runs.Finish();
  pend.Finish();
  c.attitude_steps = PathOf(map, "attitude_steps");
  if (map.Has("flight")) c.flight = PathOf(map, "flight");
  map.Finish();
  return c;
}

Campaign LoadCampaignFile(const std::string& path) {
  return ParseCampaign(YamlMap::LoadFile(path));
}

}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

#include "fnmpc/config/yaml_reader.hpp"

namespace fnmpc::config {

/// The identification campaign file (docs/data-formats.md, "Campaign file"). Paths are
/// resolved relative to the campaign file's directory.
struct Campaign {
  std::string name;              ///< free text
  double mass = 0.0;             ///< [kg], measured on a scale
  double arm_length = 0.0;       ///< [m]
  std::string propeller_bench;   ///< bench.csv path
  double wire_separation = 0.0;  ///< bifilar pendulum: distance between the wires d [m]
  double wire_length = 0.0;      ///< bifilar pendulum: wire length L [m]
  std::string pendulum_x;        ///< swing about body x (CSV path)
  std::string pendulum_y;        ///< swing about body y (CSV path)
  std::string pendulum_z;        ///< swing about body z (CSV path)
  std::string attitude_steps;    ///< attitude step log (CSV path)
  std::string flight;            ///< closed-loop flight (CSV path), empty when absent
};

/// Reads and validates a campaign file; unknown, missing or mistyped keys and non-positive
/// lengths or mass throw ConfigError with file, line, column and key.
Campaign LoadCampaignFile(const std::string& path);
/// Same on a parsed mapping (relative paths against map.directory()).
Campaign ParseCampaign(YamlMap map);

}  // namespace fnmpc::config

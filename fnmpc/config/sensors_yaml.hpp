// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <vector>

#include "fnmpc/config/settings_doc.hpp"
#include "fnmpc/config/yaml_reader.hpp"
#include "fnmpc/core/sensors.hpp"

namespace fnmpc::config {

/// Highest sensor rate [Hz]: the simulator samples once per 1 ms physics step.
inline constexpr double kMaxSensorRateHz = 1000.0;

/// Reads a sensors file (config/sensors/default.yaml shows every key) by walking
/// SensorsConfig::Serialize: the top level holds any of the sensors mocap, imu, optical_flow,
/// compass, battery, relative; each holds any of its keys; anything absent keeps the
/// SensorsConfig default. Unknown sensors or keys, wrong types, values outside what Serialize
/// accepts and (enabled sensors) rate_hz outside (0, kMaxSensorRateHz] throw ConfigError
/// naming file, line and key.
SensorsConfig ParseSensors(YamlMap map);
SensorsConfig LoadSensorsFile(const std::string& path);

/// Every key of SensorsConfig::Serialize with its default, accepted values and meaning: the
/// source of docs/scenarios.md's sensors-file table (checked by scenario_settings_doc_test).
std::vector<SettingDoc> SensorsSettingsDocs();

}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

#include "fnmpc/config/yaml_reader.hpp"
#include "fnmpc/core/sensors.hpp"

namespace fnmpc::config {

/// Reads a sensors file (config/sensors/default.yaml shows every key). The top level holds
/// any of the sensors mocap, imu, optical_flow, compass, battery, relative; each holds any of
/// its keys (see the file); anything absent keeps the SensorsConfig default. Unknown sensors
/// or keys, wrong types, rate_hz <= 0, latency_s < 0, dropout_probability outside [0, 1) and
/// negative noise throw ConfigError naming file, line and key.
SensorsConfig ParseSensors(YamlMap map);
SensorsConfig LoadSensorsFile(const std::string& path);

}  // namespace fnmpc::config

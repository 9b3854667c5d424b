// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

#include "fnmpc/config/yaml_reader.hpp"
#include "fnmpc/core/sensors.hpp"

namespace fnmpc::config {

/// Highest sensor rate [Hz]: the simulator samples once per 1 ms physics step.
inline constexpr double kMaxSensorRateHz = 1000.0;

/// Reads a sensors file (config/sensors/default.yaml shows every key). The top level holds
/// any of the sensors mocap, imu, optical_flow, compass, battery, relative; each holds any of
/// its keys (see the file); anything absent keeps the SensorsConfig default. Unknown sensors
/// or keys, wrong types, rate_hz outside (0, kMaxSensorRateHz], latency_s outside [0, 10],
/// dropout_probability outside [0, 1) and noise <= 0 (battery voltage noise and range noise
/// growth: < 0) throw ConfigError naming file, line and key.
SensorsConfig ParseSensors(YamlMap map);
SensorsConfig LoadSensorsFile(const std::string& path);

}  // namespace fnmpc::config

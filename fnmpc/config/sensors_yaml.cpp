// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/sensors_yaml.hpp"

#include "fnmpc/config/settings_yaml.hpp"

namespace fnmpc::config {

SensorsConfig ParseSensors(YamlMap map) {
  SensorsConfig c;
  SettingsReader reader(&map);
  reader.Read(&c);
  // rate_hz is checked only when the sensor is on (a disabled sensor may carry any rate).
  for (auto [name, spec] :
       {std::pair{"mocap", &c.mocap}, std::pair{"imu", &c.imu},
        std::pair{"optical_flow", &c.optical_flow}, std::pair{"compass", &c.compass},
        std::pair{"battery", &c.battery}, std::pair{"relative", &c.relative}}) {
    YamlMap* m = reader.At(name);
    if (m == nullptr || !spec->enabled ||
        (spec->rate_hz > 0.0 && spec->rate_hz <= kMaxSensorRateHz))
      continue;
    throw m->ErrorAt("rate_hz",
                     "must be > 0 and <= " + std::to_string(static_cast<int>(kMaxSensorRateHz)) +
                         " Hz (the physics rate), got " + std::to_string(spec->rate_hz));
  }
  reader.Finish();
  map.Finish();
  return c;
}

SensorsConfig LoadSensorsFile(const std::string& path) {
  return ParseSensors(YamlMap::LoadFile(path));
}

std::vector<SettingDoc> SensorsSettingsDocs() {
  SensorsConfig defaults;
  SettingsDocWriter writer;
  writer.Read(&defaults);
  return writer.fields();
}

}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <fstream>
#include <sstream>
#include <string>

namespace fnmpc::config::test {

/// The text of a shipped scenario (config/scenarios/<name>), with its relative vehicle and
/// sensors file paths made absolute so that it parses without a directory (LoadString).
inline std::string ShippedScenarioText(const std::string& name) {
  std::ifstream f(std::string(FNMPC_SOURCE_DIR) + "/config/scenarios/" + name);
  std::stringstream s;
  s << f.rdbuf();
  std::string text = s.str();
  const std::string root = std::string(FNMPC_SOURCE_DIR) + "/config/";
  for (const std::string key : {"vehicles/", "sensors/"}) {
    const std::string rel = "../" + key;
    for (std::size_t p = text.find(rel); p != std::string::npos; p = text.find(rel))
      text.replace(p, rel.size(), root + key);
  }
  return text;
}

}  // namespace fnmpc::config::test

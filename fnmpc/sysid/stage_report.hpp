// SPDX-License-Identifier: BSD-3-Clause
// One stage of the identification pipeline as `fnmpc sysid` and `fnmpc calibrate` report it
// (summary.json's "stages", the report's table): parameters, residuals, sanity checks.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <utility>

namespace fnmpc::sysid {

/// One independent stage of the identification pipeline (propulsion, inertia, ...).
struct StageReport {
  explicit StageReport(std::string stage_name) : name(std::move(stage_name)) {}
  std::string name;
  bool ok = false;     ///< ran and produced its parameters
  std::string reason;  ///< why it did not (the error message), empty when ok
  nlohmann::json params = nlohmann::json::array();  ///< {name, value, std_error, unit}
  nlohmann::json checks = nlohmann::json::array();  ///< {name, value, limit, pass}
  nlohmann::json residuals = nlohmann::json::object();

  /// Adds an identified parameter; std_error < 0 or NaN: not available.
  void Param(const std::string& param, double value, double std_error, const std::string& unit);
  /// Adds a sanity check "value <= limit" (upper = true) or "value >= limit".
  void Check(const std::string& check, double value, double limit, bool upper = true);
  /// Adds a sanity check with a precomputed outcome.
  void CheckTrue(const std::string& check, bool pass, const std::string& detail);
  /// Every sanity check passed (and the stage ran).
  [[nodiscard]] bool Passed() const;
  /// Names of the failed sanity checks, comma-separated (empty: none failed).
  [[nodiscard]] std::string FailedChecks() const;
  [[nodiscard]] nlohmann::json Json() const;
};

}  // namespace fnmpc::sysid

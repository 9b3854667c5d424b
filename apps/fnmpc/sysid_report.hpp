// SPDX-License-Identifier: BSD-3-Clause
// Report helpers of `fnmpc sysid` and `fnmpc calibrate`: per-stage records (parameters with
// standard errors, residuals, sanity checks), CSV dumps, the report directory and the
// plotting script (started without a shell).
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

namespace fnmpc::app::sysid_report {

namespace fs = std::filesystem;

/// One independent stage of the identification pipeline (propulsion, inertia, ...).
struct Stage {
  explicit Stage(std::string stage_name) : name(std::move(stage_name)) {}
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

/// Writes a CSV file with a header and rows of numbers (full precision).
void WriteCsv(const fs::path& path, const std::vector<std::string>& header,
              const std::vector<std::vector<double>>& columns);

/// The report directory of an output file: <out>.report.
fs::path ReportDir(const std::string& out);

/// Runs tools/sysid_report.py on `tmp` (warning only on failure), then replaces `final_dir`
/// with `tmp` (rename).
void Finalize(const fs::path& tmp, const fs::path& final_dir, bool plots);

/// A fresh temporary directory next to `final_dir`.
fs::path MakeTemp(const fs::path& final_dir);

/// Prints the stages as a table on stdout (name, status, checks).
void PrintStages(const std::vector<Stage>& stages);

}  // namespace fnmpc::app::sysid_report

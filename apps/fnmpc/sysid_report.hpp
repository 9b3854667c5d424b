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

#include "fnmpc/sysid/stage_report.hpp"

namespace fnmpc::app::sysid_report {

namespace fs = std::filesystem;

/// One stage of the pipeline (fnmpc/sysid/stage_report.hpp).
using Stage = sysid::StageReport;

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

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <vector>

#include "fnmpc/config/yaml_reader.hpp"

namespace fnmpc::config {

/// The required numeric columns of one CSV file (docs/data-formats.md: one header row,
/// comma separated, columns in any order, extra columns ignored).
class CsvTable {
 public:
  /// The values of required column `name`; throws std::invalid_argument for a column that
  /// was not requested.
  [[nodiscard]] const std::vector<double>& Column(const std::string& name) const;
  /// Number of data rows.
  [[nodiscard]] std::size_t rows() const { return rows_; }
  /// The file the table was read from.
  [[nodiscard]] const std::string& file() const { return file_; }

 private:
  friend CsvTable ParseCsv(const std::string&, const std::string&, const std::vector<std::string>&,
                           const std::string&, bool);
  std::string file_;
  std::vector<std::string> names_;
  std::vector<std::vector<double>> columns_;
  std::size_t rows_ = 0;
};

/// Reads `path` and returns the `required` columns. A missing file, a missing required
/// column, a row with too few cells, a non-numeric, NaN or infinite cell, no data rows, or
/// (when `time_column` is not empty) a time that does not increase strictly throw
/// ConfigError "file:line:column: column 'name': what" (line and character column 1-based;
/// a missing column names the header line). With `hash_comments`, lines starting with '#'
/// are skipped (reference tables that carry their source above the header).
CsvTable ReadCsv(const std::string& path, const std::vector<std::string>& required,
                 const std::string& time_column = "", bool hash_comments = false);

/// Same as ReadCsv on CSV text; `name` stands for the file name in messages.
CsvTable ParseCsv(const std::string& text, const std::string& name,
                  const std::vector<std::string>& required, const std::string& time_column = "",
                  bool hash_comments = false);

}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/csv_reader.hpp"

#include "fnmpc/config/text_file.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace fnmpc::config {
namespace {

struct Cell {
  std::string text;
  int column = 1;  // 1-based character column of the cell's first character
};

std::vector<Cell> SplitLine(const std::string& line) {
  std::vector<Cell> cells;
  Cell cur;
  cur.column = 1;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (line[i] == ',') {
      cells.push_back(cur);
      cur = Cell{};
      cur.column = static_cast<int>(i) + 2;
    } else {
      cur.text.push_back(line[i]);
    }
  }
  cells.push_back(cur);
  return cells;
}

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

std::string Where(const std::string& file, int line, int column) {
  return file + ":" + std::to_string(line) + ":" + std::to_string(column);
}

}  // namespace

const std::vector<double>& CsvTable::Column(const std::string& name) const {
  const auto it = std::find(names_.begin(), names_.end(), name);
  if (it == names_.end()) {
    throw std::invalid_argument("[CsvTable] " + file_ + ": column '" + name + "' was not read");
  }
  return columns_[static_cast<std::size_t>(it - names_.begin())];
}

CsvTable ParseCsv(const std::string& text, const std::string& name,
                  const std::vector<std::string>& required, const std::string& time_column,
                  bool hash_comments) {
  const auto skipped = [hash_comments](const std::string& l) {
    const std::string t = Trim(l);
    return t.empty() || (hash_comments && t.front() == '#');
  };
  CsvTable table;
  table.file_ = name;
  table.names_ = required;
  table.columns_.resize(required.size());
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  // Header: the first non-empty line.
  std::vector<Cell> header;
  while (std::getline(in, line)) {
    ++line_no;
    if (!skipped(line)) {
      header = SplitLine(line);
      break;
    }
  }
  // Errors about the whole table name the column they stop from being read: the first
  // required one (no header) or the time column (no rows), so every error has file, line and
  // column.
  const std::string first_column = required.empty() ? time_column : required.front();
  if (header.empty()) {
    throw ConfigError(Where(name, 1, 1) + ": column '" + first_column +
                      "': empty file (no header row)");
  }
  const int header_line = line_no;
  std::vector<std::size_t> index(required.size());
  for (std::size_t r = 0; r < required.size(); ++r) {
    const auto it = std::find_if(header.begin(), header.end(),
                                 [&](const Cell& c) { return Trim(c.text) == required[r]; });
    if (it == header.end()) {
      std::string have;
      for (const auto& c : header) {
        if (!have.empty()) have.push_back(',');
        have.append(Trim(c.text));
      }
      throw ConfigError(Where(name, header_line, 1) + ": column '" + required[r] +
                        "': missing required column (header has: " + have + ")");
    }
    index[r] = static_cast<std::size_t>(it - header.begin());
  }
  const auto time_it = std::find(required.begin(), required.end(), time_column);
  const std::size_t time_r = static_cast<std::size_t>(time_it - required.begin());
  while (std::getline(in, line)) {
    ++line_no;
    if (skipped(line)) continue;
    const std::vector<Cell> cells = SplitLine(line);
    for (std::size_t r = 0; r < required.size(); ++r) {
      if (index[r] >= cells.size()) {
        throw ConfigError(Where(name, line_no, static_cast<int>(line.size()) + 1) + ": column '" +
                          required[r] + "': missing cell (row has " + std::to_string(cells.size()) +
                          " of " + std::to_string(header.size()) + " cells)");
      }
      const Cell& c = cells[index[r]];
      const std::string s = Trim(c.text);
      const std::string where = Where(name, line_no, c.column) + ": column '" + required[r] + "': ";
      char* end = nullptr;
      errno = 0;
      const double v = s.empty() ? 0.0 : std::strtod(s.c_str(), &end);
      if (s.empty() || end != s.c_str() + s.size()) {
        throw ConfigError(where + "not a number: '" + s + "'");
      }
      if (!std::isfinite(v)) throw ConfigError(where + "not a finite number: '" + s + "'");
      if (time_it != required.end() && r == time_r && !table.columns_[r].empty() &&
          !(v > table.columns_[r].back())) {
        throw ConfigError(where + "time does not increase (" + s + " after " +
                          std::to_string(table.columns_[r].back()) + ")");
      }
      table.columns_[r].push_back(v);
    }
    ++table.rows_;
  }
  if (table.rows_ == 0) {
    const std::string column = time_column.empty() ? first_column : time_column;
    throw ConfigError(Where(name, header_line, 1) + ": column '" + column + "': no data rows");
  }
  return table;
}

CsvTable ReadCsv(const std::string& path, const std::vector<std::string>& required,
                 const std::string& time_column, bool hash_comments) {
  return ParseCsv(ReadTextFile(path), path, required, time_column, hash_comments);
}

}  // namespace fnmpc::config

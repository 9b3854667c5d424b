// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/settings_doc.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

namespace fnmpc::config {

void SettingsDocWriter::VisitRange(std::string_view key, double* lo, double* hi,
                                   const RangeLimit& limit, std::string_view doc) {
  std::string range = "[";
  range.append(Format(*lo / limit.unit_value))
      .append(", ")
      .append(Format(*hi / limit.unit_value))
      .append("]");
  fields_.push_back({Key(key), range, limit.Describe(), std::string(doc)});
}

std::string SettingsDocWriter::Format(double v) { return std::isnan(v) ? "none" : Limit::Num(v); }
std::string SettingsDocWriter::Format(int v) { return std::to_string(v); }
std::string SettingsDocWriter::Format(bool v) { return v ? "true" : "false"; }
std::string SettingsDocWriter::Format(const Vec3& v) {
  if (v.array().isNaN().all()) return "none";
  std::string s = "[";
  s.append(Format(v.x())).append(", ").append(Format(v.y())).append(", ").append(Format(v.z()));
  return s.append("]");
}

std::string SettingsTable(const std::vector<SettingDoc>& fields) {
  std::ostringstream s;
  s << "| key | default | accepts | meaning |\n|---|---|---|---|\n";
  for (const SettingDoc& f : fields) {
    std::string doc = f.doc;
    for (std::size_t p = doc.find('|'); p != std::string::npos; p = doc.find('|', p + 2))
      doc.replace(p, 1, "\\|");
    s << "| `" << f.key << "` | " << f.default_value << " | " << f.accepts << " | " << doc
      << " |\n";
  }
  return s.str();
}

std::string TableBegin(std::string_view table) {
  std::string m = "<!-- ";
  return m.append(table).append(
      " table: generated from the Serialize definitions, do not edit -->");
}

std::string TableEnd(std::string_view table) {
  std::string m = "<!-- end of ";
  return m.append(table).append(" table -->");
}

namespace {

/// The text between the markers of `table`, or npos positions when a marker is missing.
std::pair<std::size_t, std::size_t> Block(const std::string& markdown, std::string_view table) {
  const std::string begin = TableBegin(table);
  const std::size_t b = markdown.find(begin);
  if (b == std::string::npos) return {std::string::npos, std::string::npos};
  const std::size_t start = b + begin.size() + 1;  // after the marker's newline
  const std::size_t end = markdown.find(TableEnd(table), start);
  return {start, end};
}

}  // namespace

std::vector<std::string> SettingsDocDrift(const std::string& markdown,
                                          const std::vector<SettingDoc>& defined,
                                          std::string_view table) {
  std::vector<std::string> drift;
  const auto [start, end] = Block(markdown, table);
  if (start == std::string::npos || end == std::string::npos) {
    drift.push_back("the " + std::string(table) + " table markers are missing");
    return drift;
  }
  const std::string block = markdown.substr(start, end - start);
  std::vector<std::string> documented;
  std::istringstream lines(block);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("| `", 0) != 0) continue;
    const std::size_t close = line.find('`', 3);
    if (close != std::string::npos) documented.push_back(line.substr(3, close - 3));
  }
  std::set<std::string> defined_keys;
  for (const SettingDoc& f : defined) defined_keys.insert(f.key);
  const std::set<std::string> documented_keys(documented.begin(), documented.end());
  for (const std::string& k : documented) {
    if (defined_keys.count(k) == 0) drift.push_back("documented but not defined: " + k);
  }
  for (const SettingDoc& f : defined) {
    if (documented_keys.count(f.key) == 0) drift.push_back("defined but not documented: " + f.key);
  }
  if (drift.empty() && block != SettingsTable(defined)) {
    drift.push_back("the " + std::string(table) +
                    " table differs from the definitions (default, accepted values or "
                    "meaning): regenerate it");
  }
  return drift;
}

std::string WithSettingsTable(const std::string& markdown, const std::vector<SettingDoc>& defined,
                              std::string_view table) {
  const auto [start, end] = Block(markdown, table);
  if (start == std::string::npos || end == std::string::npos) return markdown;
  return markdown.substr(0, start) + SettingsTable(defined) + markdown.substr(end);
}

}  // namespace fnmpc::config

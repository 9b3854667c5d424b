// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace fnmpc::config {

/// A configuration error that names the file, the line and column (1-based) and the key.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Where a ConfigError message says it happened: "file:line:column: key 'k': what" (the
/// first ":<line>:<column>: " ends the file name, which may itself contain ':').
struct ErrorPlace {
  bool placed = false;  ///< the message starts with file:line:column
  std::string file, key, what;
  int line = 0, column = 0;
};
ErrorPlace ParseErrorPlace(const std::string& message);

/// Strict reader of one YAML mapping: every key must be read exactly as declared,
/// unknown keys are reported by Finish(), and every error carries
/// "file:line:column: key 'a.b.c': what". Used at the edge (apps, ros) only.
class YamlMap {
 public:
  /// Loads `path` and returns its top-level mapping; throws ConfigError on a missing
  /// file, a YAML syntax error (with its line) or a top level that is not a mapping.
  static YamlMap LoadFile(const std::string& path);
  /// Parses YAML text (`name` is used in messages instead of a file name).
  static YamlMap LoadString(const std::string& text, const std::string& name);

  YamlMap(YAML::Node node, std::string file, std::string prefix);

  [[nodiscard]] bool Has(const std::string& key) const;
  /// Required scalar / optional scalar with a default.
  double Double(const std::string& key);
  double Double(const std::string& key, double fallback);
  int Int(const std::string& key);
  int Int(const std::string& key, int fallback);
  bool Bool(const std::string& key, bool fallback);
  std::string String(const std::string& key);
  std::string String(const std::string& key, const std::string& fallback);
  /// A sequence of exactly `size` numbers (any size when size < 0).
  std::vector<double> Doubles(const std::string& key, int size = -1);
  Eigen::Vector3d Vector3(const std::string& key);
  Eigen::Vector3d Vector3(const std::string& key, const Eigen::Vector3d& fallback);
  /// Nested mapping (required).
  YamlMap Map(const std::string& key);
  /// Sequence of mappings (required).
  std::vector<YamlMap> MapList(const std::string& key);
  /// Raw node for special shapes; the key counts as read.
  YAML::Node Node(const std::string& key);

  /// Throws on the first key that was never read (an unknown or misspelt key).
  void Finish() const;

  /// Error at this map's own position, or at `key`'s position.
  [[nodiscard]] ConfigError Error(const std::string& what) const;
  [[nodiscard]] ConfigError ErrorAt(const std::string& key, const std::string& what) const;
  [[nodiscard]] const std::string& file() const { return file_; }
  /// Directory of the file, for resolving relative paths ("" for strings).
  [[nodiscard]] std::string directory() const;

 private:
  YAML::Node Get(const std::string& key);
  double ToDouble(const YAML::Node& n, const std::string& key) const;

  YAML::Node node_;
  std::string file_;
  std::string prefix_;
  std::set<std::string> read_;
};

}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/yaml_reader.hpp"

#include <cmath>
#include <filesystem>
#include <map>

#include "fnmpc/config/text_file.hpp"
#include "fnmpc/config/yaml_key_at_line.hpp"

namespace fnmpc::config {

namespace {
std::string Where(const std::string& file, const YAML::Mark& mark) {
  if (mark.is_null()) return file;
  return file + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

/// "name:line:column: key 'k'" for an error about the document's structure at `mark`: the
/// key is the one whose region of `text` the mark falls in (kTopLevelKey outside every key;
/// an unknown place counts as the start of the document).
std::string WhereInText(const std::string& name, const std::string& text, YAML::Mark mark) {
  if (mark.is_null()) mark = YAML::Mark();  // line 0, column 0
  return Where(name, mark) + ": key '" + YamlKeyAtLine(text, mark.line + 1) + "'";
}

/// Rejects a mapping that holds the same key twice (yaml-cpp keeps both, and a lookup would
/// silently return the first), anywhere in the document.
void RejectDuplicateKeys(const YAML::Node& node, const std::string& name, const std::string& text,
                         int depth, long* visited) {
  // Nesting deeper than any file format needs (or an alias to an enclosing node) and alias
  // chains that expand to millions of nodes are refused before they cost anything.
  if (depth > 64) {
    throw ConfigError(WhereInText(name, text, node.Mark()) + ": nesting deeper than 64 levels");
  }
  if (++*visited > 1000000) {
    throw ConfigError(WhereInText(name, text, node.Mark()) +
                      ": more than 10^6 nodes (alias expansion?)");
  }
  if (node.IsMap()) {
    std::map<std::string, YAML::Mark> seen;
    for (const auto& kv : node) {
      if (kv.first.IsScalar()) {
        const auto [it, inserted] = seen.emplace(kv.first.Scalar(), kv.first.Mark());
        if (!inserted) {
          throw ConfigError(Where(name, kv.first.Mark()) + ": key '" + kv.first.Scalar() +
                            "': duplicate key (first at line " +
                            std::to_string(it->second.line + 1) + ")");
        }
      }
      RejectDuplicateKeys(kv.second, name, text, depth + 1, visited);
    }
  } else if (node.IsSequence()) {
    for (const auto& e : node) RejectDuplicateKeys(e, name, text, depth + 1, visited);
  }
}

/// "name:line:column: key 'k'" of byte `pos` of `text` (the key as in WhereInText).
std::string WhereByte(const std::string& name, const std::string& text, std::size_t pos) {
  int line = 1, column = 1;
  for (std::size_t i = 0; i < pos && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return name + ":" + std::to_string(line) + ":" + std::to_string(column) + ": key '" +
         YamlKeyAtLine(text, line) + "'";
}

YamlMap FromRoot(const YAML::Node& root, const std::string& name) {
  if (!root.IsMap()) {
    // An empty document has no mark: its place is the start of the file.
    const std::string where = root.Mark().is_null() ? name + ":1:1" : Where(name, root.Mark());
    throw ConfigError(where + ": key '" + kTopLevelKey + "': expected a mapping at the top level");
  }
  return {root, name, ""};
}
}  // namespace

YamlMap YamlMap::LoadFile(const std::string& path) { return LoadString(ReadTextFile(path), path); }

YamlMap YamlMap::LoadString(const std::string& text, const std::string& name) {
  const std::size_t bad = FindInvalidUtf8(text);
  if (bad != std::string::npos) {
    throw ConfigError(WhereByte(name, text, bad) + ": invalid UTF-8 byte");
  }
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(WhereInText(name, text, e.mark) + ": YAML syntax error: " + e.msg);
  }
  long visited = 0;
  RejectDuplicateKeys(root, name, text, 0, &visited);
  return FromRoot(root, name);
}

YamlMap::YamlMap(YAML::Node node, std::string file, std::string prefix)
    : node_(std::move(node)), file_(std::move(file)), prefix_(std::move(prefix)) {}

bool YamlMap::Has(const std::string& key) const { return static_cast<bool>(node_[key]); }

ConfigError YamlMap::Error(const std::string& what) const {
  // The map's own key is its prefix without the trailing '.'.
  const std::string key = prefix_.empty() ? kTopLevelKey : prefix_.substr(0, prefix_.size() - 1);
  return ConfigError(Where(file_, node_.Mark()) + ": key '" + key + "': " + what);
}

ConfigError YamlMap::ErrorAt(const std::string& key, const std::string& what) const {
  const YAML::Node n = node_[key];
  const YAML::Mark mark = n ? n.Mark() : node_.Mark();
  return ConfigError(Where(file_, mark) + ": key '" + prefix_ + key + "': " + what);
}

std::string YamlMap::directory() const {
  const auto parent = std::filesystem::path(file_).parent_path();
  return parent.string();
}

YAML::Node YamlMap::Get(const std::string& key) {
  const YAML::Node n = node_[key];
  if (!n) throw ErrorAt(key, "missing required key");
  read_.insert(key);
  return n;
}

double YamlMap::ToDouble(const YAML::Node& n, const std::string& key) const {
  if (!n.IsScalar()) {
    throw ConfigError(Where(file_, n.Mark()) + ": key '" + prefix_ + key + "': expected a number");
  }
  double v = 0.0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    throw ConfigError(Where(file_, n.Mark()) + ": key '" + prefix_ + key +
                      "': expected a number, got '" + n.Scalar() + "'");
  }
  if (!std::isfinite(v)) {
    throw ConfigError(Where(file_, n.Mark()) + ": key '" + prefix_ + key +
                      "': expected a finite number, got '" + n.Scalar() + "'");
  }
  return v;
}

double YamlMap::Double(const std::string& key) { return ToDouble(Get(key), key); }
double YamlMap::Double(const std::string& key, double fallback) {
  return Has(key) ? Double(key) : fallback;
}

int YamlMap::Int(const std::string& key) {
  const double v = Double(key);
  if (v != std::floor(v) || std::abs(v) > 1e9) throw ErrorAt(key, "expected an integer");
  return static_cast<int>(v);
}
int YamlMap::Int(const std::string& key, int fallback) { return Has(key) ? Int(key) : fallback; }

bool YamlMap::Bool(const std::string& key, bool fallback) {
  if (!Has(key)) return fallback;
  const YAML::Node n = Get(key);
  try {
    if (n.IsScalar()) return n.as<bool>();
  } catch (const YAML::Exception&) {
  }
  throw ErrorAt(key, "expected true or false, got '" + (n.IsScalar() ? n.Scalar() : "?") + "'");
}

std::string YamlMap::String(const std::string& key) {
  const YAML::Node n = Get(key);
  if (!n.IsScalar()) throw ErrorAt(key, "expected a string");
  return n.Scalar();
}
std::string YamlMap::String(const std::string& key, const std::string& fallback) {
  return Has(key) ? String(key) : fallback;
}

std::vector<double> YamlMap::Doubles(const std::string& key, int size) {
  const YAML::Node n = Get(key);
  if (!n.IsSequence()) throw ErrorAt(key, "expected a list of numbers");
  if (size >= 0 && static_cast<int>(n.size()) != size) {
    throw ErrorAt(key,
                  "expected " + std::to_string(size) + " numbers, got " + std::to_string(n.size()));
  }
  std::vector<double> out;
  for (const auto& e : n) out.push_back(ToDouble(e, key));
  return out;
}

Eigen::Vector3d YamlMap::Vector3(const std::string& key) {
  const auto v = Doubles(key, 3);
  return {v[0], v[1], v[2]};
}
Eigen::Vector3d YamlMap::Vector3(const std::string& key, const Eigen::Vector3d& fallback) {
  return Has(key) ? Vector3(key) : fallback;
}

YamlMap YamlMap::Map(const std::string& key) {
  const YAML::Node n = Get(key);
  if (!n.IsMap()) throw ErrorAt(key, "expected a mapping");
  return {n, file_, prefix_ + key + "."};
}

std::vector<YamlMap> YamlMap::MapList(const std::string& key) {
  const YAML::Node n = Get(key);
  if (!n.IsSequence()) throw ErrorAt(key, "expected a list");
  std::vector<YamlMap> out;
  for (std::size_t i = 0; i < n.size(); ++i) {
    if (!n[i].IsMap()) {
      throw ConfigError(Where(file_, n[i].Mark()) + ": key '" + prefix_ + key + "[" +
                        std::to_string(i) + "]': expected a mapping");
    }
    out.emplace_back(n[i], file_, prefix_ + key + "[" + std::to_string(i) + "].");
  }
  return out;
}

YAML::Node YamlMap::Node(const std::string& key) { return Get(key); }

void YamlMap::Finish() const {
  for (const auto& kv : node_) {
    const std::string key = kv.first.Scalar();
    if (read_.count(key) == 0) {
      throw ConfigError(Where(file_, kv.first.Mark()) + ": unknown key '" + prefix_ + key + "'");
    }
  }
}

ErrorPlace ParseErrorPlace(const std::string& message) {
  ErrorPlace e;
  // Digits at i, then `end`; returns the position after them (npos if none).
  auto number = [&](std::size_t i, char end, int* value) -> std::size_t {
    std::size_t j = i;
    while (j < message.size() && j - i < 9 && message[j] >= '0' && message[j] <= '9') ++j;
    if (j == i || j >= message.size() || message[j] != end) return std::string::npos;
    *value = std::stoi(message.substr(i, j - i));
    return j + 1;
  };
  for (std::size_t c = message.find(':'); c != std::string::npos; c = message.find(':', c + 1)) {
    int line = 0, column = 0;
    const std::size_t after_line = number(c + 1, ':', &line);
    if (after_line == std::string::npos) continue;
    const std::size_t after_column = number(after_line, ':', &column);
    if (after_column == std::string::npos || after_column >= message.size() ||
        message[after_column] != ' ')
      continue;
    e.placed = true;
    e.file = message.substr(0, c);
    e.line = line;
    e.column = column;
    e.what = message.substr(after_column + 1);
    break;
  }
  if (!e.placed) e.what = message;
  if (const std::size_t k = message.find("key '"); k != std::string::npos) {
    const std::size_t end = message.find('\'', k + 5);
    if (end != std::string::npos) e.key = message.substr(k + 5, end - k - 5);
  }
  return e;
}

}  // namespace fnmpc::config

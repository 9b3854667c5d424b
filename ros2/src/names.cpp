// SPDX-License-Identifier: BSD-3-Clause
#include "names.hpp"

#include <cctype>
#include <stdexcept>

#include <fmt/format.h>

namespace fnmpc::ros2 {
namespace {

void CheckFullyQualified(const std::string& original, const std::string& name) {
  if (name.empty() || name[0] != '/') {
    throw std::invalid_argument(
        fmt::format("ROS name '{}': resolves to '{}', not absolute", original, name));
  }
  if (name.size() > 1 && name.back() == '/') {
    throw std::invalid_argument(fmt::format("ROS name '{}': ends with '/'", original));
  }
  std::size_t token_start = 1;
  for (std::size_t i = 1; i <= name.size(); ++i) {
    if (i < name.size() && name[i] != '/') {
      const char c = name[i];
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) {
        throw std::invalid_argument(fmt::format(
            "ROS name '{}': character '{}' (only letters, digits, '_' and '/')", original, c));
      }
      continue;
    }
    if (i == token_start && name.size() > 1) {
      throw std::invalid_argument(fmt::format("ROS name '{}': empty token ('//')", original));
    }
    if (i > token_start && std::isdigit(static_cast<unsigned char>(name[token_start]))) {
      throw std::invalid_argument(fmt::format("ROS name '{}': token '{}' starts with a digit",
                                              original, name.substr(token_start, i - token_start)));
    }
    token_start = i + 1;
  }
}

}  // namespace

std::string ResolveName(const std::string& node_namespace, const std::string& node_name,
                        const std::string& name) {
  if (name.empty()) throw std::invalid_argument("ROS name: empty");
  std::string ns = node_namespace.empty() ? "/" : node_namespace;
  if (ns[0] != '/') ns = "/" + ns;
  const std::string prefix = ns == "/" ? "" : ns;
  std::string resolved;
  if (name[0] == '/') {
    resolved = name;
  } else if (name[0] == '~') {
    if (name.size() > 1 && name[1] != '/') {
      throw std::invalid_argument(fmt::format("ROS name '{}': '~' must be followed by '/'", name));
    }
    resolved = prefix + "/" + node_name + name.substr(1);
  } else {
    resolved = prefix + "/" + name;
  }
  CheckFullyQualified(name, resolved);
  return resolved;
}

void Remappings::Add(const std::string& rule) {
  const auto pos = rule.find(":=");
  if (pos == std::string::npos || pos == 0 || pos + 2 == rule.size()) {
    throw std::invalid_argument(fmt::format("remapping '{}': expected from:=to", rule));
  }
  rules_.emplace(rule.substr(0, pos), rule.substr(pos + 2));
}

std::string Remappings::Apply(const std::string& node_namespace, const std::string& node_name,
                              const std::string& resolved) const {
  for (const auto& [from, to] : rules_) {
    if (ResolveName(node_namespace, node_name, from) == resolved) {
      return ResolveName(node_namespace, node_name, to);
    }
  }
  return resolved;
}

std::string DdsTopicName(const std::string& fully_qualified_name) {
  CheckFullyQualified(fully_qualified_name, fully_qualified_name);
  return "rt" + fully_qualified_name;
}

}  // namespace fnmpc::ros2

// SPDX-License-Identifier: BSD-3-Clause
#include "parameters.hpp"

#include <stdexcept>

#include <fmt/format.h>

namespace fnmpc::ros2 {
namespace {

bool SectionMatches(const std::string& key, const std::string& ns, const std::string& name) {
  const std::string fqn = (ns == "/" ? "" : ns) + "/" + name;
  if (key == "/**" || key == fqn || key == "/**/" + name) return true;
  if (key.find('/') == std::string::npos && ns == "/" && key == name) return true;
  // "/*/name": exactly one namespace level.
  if (key == "/*/" + name) return ns != "/" && ns.find('/', 1) == std::string::npos;
  return false;
}

}  // namespace

NodeOptions NodeOptions::Parse(const std::vector<std::string>& args,
                               const std::string& default_node_name) {
  NodeOptions o;
  o.node_name_ = default_node_name;
  std::vector<std::string> files;
  std::vector<std::pair<std::string, std::string>> overrides;
  bool ros_args = false;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--ros-args") {
      ros_args = true;
      continue;
    }
    if (a == "--") {
      ros_args = false;
      continue;
    }
    if (!ros_args)
      throw std::invalid_argument(fmt::format("argument '{}': expected --ros-args first", a));
    auto next = [&]() -> const std::string& {
      if (i + 1 >= args.size())
        throw std::invalid_argument(fmt::format("argument '{}': missing its value", a));
      return args[++i];
    };
    if (a == "-r" || a == "--remap") {
      const std::string& rule = next();
      if (rule.rfind("__ns:=", 0) == 0) {
        o.namespace_ = rule.substr(6);
        if (o.namespace_.empty() || o.namespace_[0] != '/') o.namespace_ = "/" + o.namespace_;
        if (o.namespace_.size() > 1) ResolveName(o.namespace_, "n", "x");  // validates
      } else if (rule.rfind("__node:=", 0) == 0) {
        o.node_name_ = rule.substr(8);
      } else {
        o.remappings_.Add(rule);
      }
    } else if (a == "--params-file") {
      files.push_back(next());
    } else if (a == "-p" || a == "--param") {
      const std::string& p = next();
      const auto pos = p.find(":=");
      if (pos == std::string::npos || pos == 0) {
        throw std::invalid_argument(fmt::format("parameter '{}': expected name:=value", p));
      }
      overrides.emplace_back(p.substr(0, pos), p.substr(pos + 2));
    } else {
      throw std::invalid_argument(
          fmt::format("argument '{}': unknown (expected -r, --params-file or -p)", a));
    }
  }
  for (const auto& f : files) o.LoadFile(f);
  for (const auto& [name, value] : overrides) o.values_[name] = {YAML::Load(value), "-p " + name};
  return o;
}

void NodeOptions::LoadFile(const std::string& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    throw std::invalid_argument(fmt::format("{}: {}", file, e.what()));
  }
  if (!root.IsMap())
    throw std::invalid_argument(fmt::format("{}: expected a map of node names", file));
  for (const auto& section : root) {
    const std::string key = section.first.as<std::string>();
    const int line = section.first.Mark().line + 1;
    if (!section.second.IsMap() || !section.second["ros__parameters"]) {
      throw std::invalid_argument(
          fmt::format("{}:{}: node '{}': expected a ros__parameters map", file, line, key));
    }
    if (!SectionMatches(key, namespace_, node_name_)) continue;
    const YAML::Node params = section.second["ros__parameters"];
    if (!params.IsMap()) {
      throw std::invalid_argument(
          fmt::format("{}:{}: node '{}': ros__parameters is not a map", file, line, key));
    }
    for (const auto& p : params) {
      values_[p.first.as<std::string>()] = {p.second,
                                            fmt::format("{}:{}", file, p.second.Mark().line + 1)};
    }
  }
}

std::string NodeOptions::fully_qualified_name() const {
  return (namespace_ == "/" ? "" : namespace_) + "/" + node_name_;
}

std::string NodeOptions::Topic(const std::string& name) const {
  return DdsTopicName(
      remappings_.Apply(namespace_, node_name_, ResolveName(namespace_, node_name_, name)));
}

template <typename T>
T NodeOptions::Get(const std::string& name, const T& fallback, const char* type) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  try {
    if (!it->second.node.IsScalar()) throw YAML::Exception(YAML::Mark::null_mark(), "not a scalar");
    return it->second.node.as<T>();
  } catch (const YAML::Exception&) {
    throw std::invalid_argument(fmt::format("{}: parameter {} of {}: expected {}",
                                            it->second.origin, name, fully_qualified_name(), type));
  }
}

std::string NodeOptions::String(const std::string& name, const std::string& fallback) const {
  return Get<std::string>(name, fallback, "a string");
}
std::string NodeOptions::RequiredString(const std::string& name) const {
  const std::string v = String(name, "");
  if (v.empty()) {
    throw std::invalid_argument(
        fmt::format("missing required parameter {} of {} (a string, docs/ros2.md)", name,
                    fully_qualified_name()));
  }
  return v;
}
double NodeOptions::Double(const std::string& name, double fallback) const {
  return Get<double>(name, fallback, "a number");
}
int NodeOptions::Int(const std::string& name, int fallback) const {
  return Get<int>(name, fallback, "an integer");
}
bool NodeOptions::Bool(const std::string& name, bool fallback) const {
  return Get<bool>(name, fallback, "true or false");
}

}  // namespace fnmpc::ros2

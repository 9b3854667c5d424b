// SPDX-License-Identifier: BSD-3-Clause
// A node's command line and parameters the ROS 2 way (docs/ros2.md):
//   <node> --ros-args [-r __ns:=/leader] [-r __node:=name] [-r from:=to]...
//          [--params-file FILE]... [-p name:=value]...
// FILE in ROS 2's parameter file layout: top-level keys are node names ("/leader/vehicle_node",
// "vehicle_node", "/**", "/**/vehicle_node", "/*/vehicle_node"), each with a
// `ros__parameters` map; matching sections apply in file order, `-p` last.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "names.hpp"

namespace fnmpc::ros2 {

class NodeOptions {
 public:
  // Throws std::invalid_argument naming the argument, file, line and key on bad input.
  static NodeOptions Parse(const std::vector<std::string>& args,
                           const std::string& default_node_name);

  const std::string& node_name() const { return node_name_; }
  const std::string& node_namespace() const { return namespace_; }
  // The fully qualified name of this node ("/leader/vehicle_node").
  std::string fully_qualified_name() const;
  // A topic name resolved in this node and remapped, as a DDS topic ("rt/leader/odom").
  std::string Topic(const std::string& name) const;
  const Remappings& remappings() const { return remappings_; }

  bool Has(const std::string& name) const { return values_.count(name) != 0; }
  std::string String(const std::string& name, const std::string& fallback) const;
  std::string RequiredString(const std::string& name) const;
  double Double(const std::string& name, double fallback) const;
  int Int(const std::string& name, int fallback) const;
  bool Bool(const std::string& name, bool fallback) const;

 private:
  struct Value {
    YAML::Node node;
    std::string origin;  // "file:line" or "-p"
  };
  template <typename T>
  T Get(const std::string& name, const T& fallback, const char* type) const;
  void LoadFile(const std::string& file);

  std::string node_name_;
  std::string namespace_ = "/";
  Remappings remappings_;
  std::map<std::string, Value> values_;
};

}  // namespace fnmpc::ros2

// SPDX-License-Identifier: BSD-3-Clause
// ROS 2 names on DDS: resolution of relative and private names against a node's namespace,
// remapping, and the DDS topic name of the ROS 2 conventions ("rt" + fully qualified name).
#pragma once

#include <map>
#include <string>

namespace fnmpc::ros2 {

// A fully qualified ROS 2 name ("/leader/odom") from `name` as a node in `node_namespace`
// called `node_name` sees it: absolute ("/clock"), relative ("odom" -> "/leader/odom") or
// private ("~/status" -> "/leader/vehicle_node/status"). Throws std::invalid_argument naming the
// name and the rule it breaks (tokens of [A-Za-z0-9_], not starting with a digit, no "//").
std::string ResolveName(const std::string& node_namespace, const std::string& node_name,
                        const std::string& name);

// Remapping rules from a resolved name to another name (resolved in the same node), as
// `--ros-args -r from:=to` gives them.
class Remappings {
 public:
  // "from:=to"; throws std::invalid_argument on a rule without ":=".
  void Add(const std::string& rule);
  // The resolved name after the rules (the first rule whose resolved `from` matches).
  std::string Apply(const std::string& node_namespace, const std::string& node_name,
                    const std::string& resolved) const;

 private:
  std::multimap<std::string, std::string> rules_;  // unresolved from -> unresolved to
};

// "rt" + fully qualified topic name: the DDS topic a ROS 2 topic is carried on.
std::string DdsTopicName(const std::string& fully_qualified_name);

}  // namespace fnmpc::ros2

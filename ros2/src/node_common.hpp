// SPDX-License-Identifier: BSD-3-Clause
// What the nodes share: their main (stop on SIGINT/SIGTERM, options, fatal errors), logging
// with the node's name, the QoS of the sensor streams (docs/ros2.md).
#pragma once

#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "dds_node.hpp"
#include "parameters.hpp"

namespace fnmpc::ros2 {

inline std::atomic<bool>& StopRequested() {
  static std::atomic<bool> stop{false};
  return stop;
}

inline void InstallStopHandlers() {
  auto handler = [](int) { StopRequested() = true; };
  std::signal(SIGINT, handler);
  std::signal(SIGTERM, handler);
}

// Lockstep needs every measurement (the fusion order counts them): reliable, deep enough for a
// control period of IMU samples. Free-running flight uses ROS 2's sensor-data profile.
inline QosProfile SensorQos(bool lockstep) {
  return lockstep ? QosProfile{true, 1000} : QosProfile::SensorData();
}
// The run's other streams (setpoints, estimates, status, ground truth, /clock): ROS 2's default
// profile, deepened in lockstep, where the simulator runs many times faster than real time and a
// KEEP_LAST 10 writer drops samples a remote reader has not acknowledged yet (a Fast DDS reader
// missed half the setpoints of a run that way).
inline QosProfile StreamQos(bool lockstep) {
  return lockstep ? QosProfile{true, 1000} : QosProfile::Default();
}

/// A node's main: stop handlers, the options parsed from argv (default node name `name`),
/// `body(options)`'s exit code; an exception is printed as "[name] fatal: ..." and exits 1.
template <typename Body>
int RunNodeMain(int argc, char** argv, const char* name, Body body) {
  InstallStopHandlers();
  try {
    return body(NodeOptions::Parse(std::vector<std::string>(argv + 1, argv + argc), name));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "[%s] fatal: %s\n", name, e.what());
    return 1;
  }
}

template <typename... Args>
void Log(const std::string& node, fmt::format_string<Args...> format, Args&&... args) {
  std::fprintf(stderr, "[%s] %s\n", node.c_str(),
               fmt::format(format, std::forward<Args>(args)...).c_str());
}

}  // namespace fnmpc::ros2

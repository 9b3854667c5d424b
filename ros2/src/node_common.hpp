// SPDX-License-Identifier: BSD-3-Clause
// What both nodes share: stop on SIGINT/SIGTERM, logging with the node's name, the QoS of the
// sensor streams (docs/ros2.md).
#pragma once

#include <atomic>
#include <csignal>
#include <cstdio>
#include <string>

#include <fmt/format.h>

#include "dds_node.hpp"

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

template <typename... Args>
void Log(const std::string& node, fmt::format_string<Args...> format, Args&&... args) {
  std::fprintf(stderr, "[%s] %s\n", node.c_str(),
               fmt::format(format, std::forward<Args>(args)...).c_str());
}

}  // namespace fnmpc::ros2

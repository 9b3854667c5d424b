#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Builds the ROS 1 package (ros/fnmpc_ros, Release) in build-ros and runs its rostests
# (docs/ros.md): triangle flight, one follower node killed mid-flight, ROS vs `fnmpc run`.
# Exits non-zero when the build or a test fails.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh --with-ros
# Debian's python3 first: a pyenv python3 lacks catkin_pkg and rospy (dependency notes).
export PATH=/usr/bin:$PATH
# ROS state and logs in a temporary folder; master on loopback (rostest starts its own).
ros_tmp=$(mktemp -d /tmp/fnmpc-ros.XXXXXX)
export ROS_HOME=$ros_tmp ROS_LOG_DIR=$ros_tmp/log ROSCONSOLE_STDOUT_LINE_BUFFERED=1
export ROS_IP=127.0.0.1 ROS_MASTER_URI=http://127.0.0.1:11311

cmake -S ros/fnmpc_ros -B build-ros -DCMAKE_BUILD_TYPE=Release
cmake --build build-ros -j"$(nproc)"
cd build-ros
status=0
ctest --output-on-failure || status=$?
if [[ $status -ne 0 ]]; then echo "test-ros: FAILED (logs: $ROS_LOG_DIR)"; exit "$status"; fi
rm -rf "$ros_tmp"
echo "test-ros: all rostests passed"

# SPDX-License-Identifier: BSD-3-Clause
# Whether the ROS 2 interface (ros2/, docs/ros2.md) can be built: Debian's Cyclone DDS (cyclonedds-dev,
# idlc from cyclonedds-tools), Fast DDS (libfastrtps-dev, the independent implementation of the
# interoperability test) and rosidl's .msg parser (python3-rosidl) for /usr/bin/python3.
# Sets FNMPC_ROS2_FOUND; installed by scripts/install-deps.sh --with-ros2.
set(FNMPC_ROS2_PYTHON /usr/bin/python3 CACHE FILEPATH "Python with rosidl_adapter (python3-rosidl) for ros2/")
find_package(CycloneDDS 0.10 QUIET CONFIG)
find_package(fastrtps 2.9 QUIET CONFIG)
find_program(FNMPC_IDLC idlc)
set(FNMPC_ROS2_FOUND OFF)
if(CycloneDDS_FOUND AND fastrtps_FOUND AND FNMPC_IDLC AND EXISTS ${FNMPC_ROS2_PYTHON})
  execute_process(COMMAND ${FNMPC_ROS2_PYTHON} -c "import rosidl_adapter.parser"
                  RESULT_VARIABLE _fnmpc_rosidl_result OUTPUT_QUIET ERROR_QUIET)
  if(_fnmpc_rosidl_result EQUAL 0)
    set(FNMPC_ROS2_FOUND ON)
  endif()
endif()

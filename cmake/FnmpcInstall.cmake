# SPDX-License-Identifier: BSD-3-Clause
# `cmake --install <build> --prefix <prefix>`: the algorithm layers that need nothing but
# Eigen (core, mavlink, model, qp, ocp, rti, estimation, formation) as the CMake package `fnmpc`:
#   <prefix>/include/fnmpc/<layer>/*.hpp
#   <prefix>/lib/libfnmpc_<layer>.a
#   <prefix>/lib/cmake/fnmpc/{fnmpcConfig,fnmpcConfigVersion,fnmpcTargets}.cmake
# so that `find_package(fnmpc CONFIG REQUIRED)` gives the targets fnmpc::<layer>. The
# simulator joins them when it is built (MuJoCo, below); the configuration and sysid layers
# (yaml-cpp, Ceres), the benchmark problems of `fnmpc bench` (bench/ocp_spec) and the CLI are
# not part of the package.
include(CMakePackageConfigHelpers)
include(GNUInstallDirs)

set(FNMPC_INSTALLED_LAYERS core mavlink link autopilot model qp ocp rti estimation formation)
set(fnmpc_install_targets "")
foreach(layer IN LISTS FNMPC_INSTALLED_LAYERS)
  if(NOT TARGET fnmpc_${layer})
    message(STATUS "fnmpc: layer ${layer} not built, the installed package has no fnmpc::${layer}")
    continue()
  endif()
  list(APPEND fnmpc_install_targets fnmpc_${layer})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/fnmpc/${layer}/
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/fnmpc/${layer}
          FILES_MATCHING PATTERN "*.hpp")
endforeach()
# The simulator, when this build has it (MuJoCo): fnmpc::sim, for programs that fly a
# controller in simulation (examples/simulate.cpp). Its MuJoCo link goes with it as
# fnmpc::mujoco_headless (the include directory and library this build found, by their paths).
set(fnmpc_has_sim OFF)
if(TARGET fnmpc_sim)
  set(fnmpc_has_sim ON)
  list(APPEND fnmpc_install_targets fnmpc_sim mujoco_headless)
  set_target_properties(mujoco_headless PROPERTIES EXPORT_NAME mujoco_headless)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/fnmpc/sim/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/fnmpc/sim
          FILES_MATCHING PATTERN "*.hpp")
endif()
install(TARGETS ${fnmpc_install_targets} EXPORT fnmpcTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

set(fnmpc_cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/fnmpc)
install(EXPORT fnmpcTargets NAMESPACE fnmpc:: DESTINATION ${fnmpc_cmake_dir})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/fnmpcConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/fnmpcConfig.cmake
                              INSTALL_DESTINATION ${fnmpc_cmake_dir})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/fnmpcConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/fnmpcConfig.cmake ${PROJECT_BINARY_DIR}/fnmpcConfigVersion.cmake
        DESTINATION ${fnmpc_cmake_dir})

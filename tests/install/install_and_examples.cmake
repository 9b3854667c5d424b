# SPDX-License-Identifier: BSD-3-Clause
# cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... -DGENERATOR=... -DCXX=... [-DWITH_SIM=ON]
#       -P <this>
# (see CMakeLists.txt here).
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "install_and_examples: '${ARGN}' failed (${rc})")
  endif()
endfunction()

file(REMOVE_RECURSE ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f lib/cmake/fnmpc/fnmpcConfig.cmake lib/cmake/fnmpc/fnmpcConfigVersion.cmake
          include/fnmpc/rti/rti_solver.hpp include/fnmpc/core/eigen_abi.hpp
          include/fnmpc/formation/vehicle_controller.hpp)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "install_and_examples: ${f} not installed")
  endif()
endforeach()
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples -B ${WORK_DIR}/build -G ${GENERATOR}
    -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_PREFIX_PATH=${prefix})
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)
set(examples cart_rti quadrotor_waypoints formation_controller)
if(WITH_SIM)
  list(APPEND examples simulate)
endif()
foreach(example IN LISTS examples)
  if(NOT EXISTS ${WORK_DIR}/build/${example})
    message(FATAL_ERROR "install_and_examples: example ${example} was not built")
  endif()
  run(${WORK_DIR}/build/${example})
endforeach()

# SPDX-License-Identifier: BSD-3-Clause
# fnmpc_add_layer(NAME SOURCES ... DEPS ...): one static library per layer,
# target fnmpc_<name>, alias fnmpc::<name> (also its name in the installed package, see
# cmake/FnmpcInstall.cmake), includes rooted at the repository (the install prefix's include/
# once installed).
function(fnmpc_add_layer name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  if(ARG_SOURCES)
    add_library(fnmpc_${name} STATIC ${ARG_SOURCES})
    target_include_directories(fnmpc_${name} PUBLIC $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>
                                                $<INSTALL_INTERFACE:include>)
    target_link_libraries(fnmpc_${name} PUBLIC ${ARG_DEPS})
  else()
    add_library(fnmpc_${name} INTERFACE)
    target_include_directories(fnmpc_${name} INTERFACE $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>
                                                   $<INSTALL_INTERFACE:include>)
    target_link_libraries(fnmpc_${name} INTERFACE ${ARG_DEPS})
  endif()
  set_target_properties(fnmpc_${name} PROPERTIES EXPORT_NAME ${name})
  add_library(fnmpc::${name} ALIAS fnmpc_${name})
endfunction()

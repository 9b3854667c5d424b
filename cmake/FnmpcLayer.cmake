# SPDX-License-Identifier: BSD-3-Clause
# fnmpc_add_layer(NAME SOURCES ... DEPS ...): one static library per layer,
# target fnmpc_<name>, alias fnmpc::<name>, includes rooted at the repository.
function(fnmpc_add_layer name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  if(ARG_SOURCES)
    add_library(fnmpc_${name} STATIC ${ARG_SOURCES})
    target_include_directories(fnmpc_${name} PUBLIC ${PROJECT_SOURCE_DIR})
    target_link_libraries(fnmpc_${name} PUBLIC ${ARG_DEPS})
  else()
    add_library(fnmpc_${name} INTERFACE)
    target_include_directories(fnmpc_${name} INTERFACE ${PROJECT_SOURCE_DIR})
    target_link_libraries(fnmpc_${name} INTERFACE ${ARG_DEPS})
  endif()
  add_library(fnmpc::${name} ALIAS fnmpc_${name})
endfunction()

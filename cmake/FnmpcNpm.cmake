# SPDX-License-Identifier: BSD-3-Clause
# npm packages pinned in a package-lock.json, installed into the build tree at build time
# (the replay viewer, the MAVLink interop test).
#   fnmpc_npm_ci(WORK <dir> SOURCE <dir> COMMENT <text>)
# adds the build step that copies SOURCE's package.json and package-lock.json into WORK and
# runs `npm ci` there; its output is WORK/node_modules/.package-lock.json. FNMPC_NODE and
# FNMPC_NPM are the programs found (empty without Node.js and npm: the callers skip then).
find_program(FNMPC_NPM npm)
find_program(FNMPC_NODE NAMES node nodejs)

function(fnmpc_npm_ci)
  cmake_parse_arguments(ARG "" "WORK;SOURCE;COMMENT" "" ${ARGN})
  file(MAKE_DIRECTORY ${ARG_WORK})
  add_custom_command(
    OUTPUT ${ARG_WORK}/node_modules/.package-lock.json
    COMMAND ${CMAKE_COMMAND} -E copy ${ARG_SOURCE}/package.json ${ARG_SOURCE}/package-lock.json
            ${ARG_WORK}
    COMMAND ${FNMPC_NPM} ci --no-audit --no-fund --loglevel=error
    WORKING_DIRECTORY ${ARG_WORK}
    DEPENDS ${ARG_SOURCE}/package.json ${ARG_SOURCE}/package-lock.json
    COMMENT "${ARG_COMMENT}")
endfunction()

# SPDX-License-Identifier: BSD-3-Clause
# msg2idl.py on bad .msg files: exit 1 and a message naming the file (and the field).
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK}/msg/bad_msgs)
file(WRITE ${WORK}/msg/bad_msgs/BadType.msg "float64 x\nfloat65 y\n")
file(WRITE ${WORK}/msg/bad_msgs/Bounded.msg "float64[<=3] limits\n")
file(WRITE ${WORK}/msg/bad_msgs/Missing.msg "bad_msgs/Nowhere n\n")
foreach(case "BadType;BadType.msg" "Bounded;Bounded.msg: field limits: bounded sequences"
             "Missing;references bad_msgs/msg/Nowhere")
  list(GET case 0 name)
  list(GET case 1 expected)
  execute_process(COMMAND ${PYTHON} ${SCRIPT} ${WORK}/msg ${WORK}/out ${WORK}/out/h.hpp bad_msgs/${name}
                  RESULT_VARIABLE rc ERROR_VARIABLE err OUTPUT_QUIET)
  if(NOT rc EQUAL 1)
    message(FATAL_ERROR "${name}: exit ${rc}, expected 1 (stderr: ${err})")
  endif()
  string(FIND "${err}" "${expected}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "${name}: stderr does not name '${expected}': ${err}")
  endif()
  message(STATUS "${name}: ${err}")
endforeach()

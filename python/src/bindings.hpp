// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pybind11/pybind11.h>

/// The parts of the Python module fnmpc._fnmpc, one file each (docs/python.md).
namespace fnmpc::python {

void BindConfig(pybind11::module_& m);  ///< vehicle, sensor and scenario files; ConfigError
void BindOcp(pybind11::module_& m);     ///< the shipped OCPs (leader, follower, reduced)
void BindWorld(pybind11::module_& m);   ///< the simulator world
void BindRunner(pybind11::module_& m);  ///< closed-loop runs (`fnmpc run`)

}  // namespace fnmpc::python

// SPDX-License-Identifier: BSD-3-Clause
// fnmpc._fnmpc: the compiled part of the Python package fnmpc (python/fnmpc/__init__.py
// adds the pure-Python helpers, e.g. run() with the logs as numpy structured arrays).
#include "python/src/bindings.hpp"

PYBIND11_MODULE(_fnmpc, m) {
  m.doc() =
      "fnmpc: decentralized NMPC of multi-rotor formations (C++ core). Configuration files, "
      "the shipped optimal control problems, the MuJoCo simulator world and closed-loop runs.";
  fnmpc::python::BindConfig(m);
  fnmpc::python::BindOcp(m);
  fnmpc::python::BindWorld(m);
  fnmpc::python::BindRunner(m);
}

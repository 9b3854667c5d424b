// SPDX-License-Identifier: BSD-3-Clause
// Closed-loop runs as `fnmpc run` does them (fnmpc/experiment/run_folder.hpp). The summary comes
// back as JSON text so that Python parses exactly what summary.json holds; fnmpc.run()
// (python/fnmpc/__init__.py) adds the logs as numpy structured arrays.
#include <pybind11/stl.h>

#include <string>

#include "fnmpc/experiment/run_folder.hpp"
#include "python/src/bindings.hpp"

namespace py = pybind11;

namespace fnmpc::python {

void BindRunner(py::module_& m) {
  m.def(
      "_run_folder",
      [](const config::ScenarioConfig& sc, const std::string& dir, int runs, std::int64_t seed,
         bool progress) {
        experiment::RunFolderOptions o;
        o.runs = runs;
        o.seed = seed;
        o.progress = progress;
        o.scenario_file = sc.file;
        nlohmann::json summary;
        {
          py::gil_scoped_release release;
          summary = experiment::RunFolder(sc, o, dir);
        }
        return summary.dump(2);
      },
      py::arg("scenario"), py::arg("dir"), py::arg("runs") = 1, py::arg("seed") = -1,
      py::arg("progress") = false,
      "Runs `runs` simulations (seeds seed, seed + 1, ...; seed < 0: the scenario's) into "
      "the run folder `dir` and returns summary.json's text. Use fnmpc.run().");
}

}  // namespace fnmpc::python

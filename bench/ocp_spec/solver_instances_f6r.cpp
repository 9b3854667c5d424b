// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/ocp/problems.hpp"
#include "fnmpc/rti/rti_solver.hpp"

namespace fnmpc::rti {
template class RtiSolver<ocp::ReducedFollowerProblem<6>>;
}  // namespace fnmpc::rti

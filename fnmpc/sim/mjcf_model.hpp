// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <mujoco/mujoco.h>

#include <string>

namespace fnmpc::sim {

/// Compiles MJCF text held in memory into a MuJoCo model (through an in-memory VFS, no file).
/// MuJoCo's XML compiler is not documented as thread-safe and worlds may be built from several
/// threads (`fnmpc run --jobs`): compilations are serialised by a process-wide mutex. Throws
/// std::runtime_error starting with `who` when MuJoCo rejects the model. The caller owns the
/// model (mj_deleteModel).
///
/// The first call also routes MuJoCo's warnings to stderr ("MuJoCo warning: ..."), unless
/// the program installed its own `mju_user_warning`: MuJoCo's default handler appends every
/// warning to MUJOCO_LOG.TXT in the working directory. The World turns the warnings that
/// matter into SimulationError from its counters (docs/failure.md), so nothing is lost.
[[nodiscard]] mjModel* CompileMjcf(const std::string& xml, const std::string& who);

}  // namespace fnmpc::sim

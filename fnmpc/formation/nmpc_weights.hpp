// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include "fnmpc/ocp/nmpc_weights.hpp"

namespace fnmpc::formation {

/// The controllers' NMPC weights: the quadrotor problems' own struct (fnmpc/ocp).
using NmpcWeights = ocp::NmpcWeights;

}  // namespace fnmpc::formation

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/estimation/vehicle_ekf.hpp"

#include <gtest/gtest.h>

namespace fnmpc::estimation {
namespace {}
}  // namespace fnmpc::estimation

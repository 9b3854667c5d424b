// SPDX-License-Identifier: BSD-3-Clause
// Writes the reference figures of cross_arch_test (tests/onboard/cross_arch_cases.hpp) as CSV
// to stdout. The committed file comes from an x86-64 Release build:
//   ./build/tests/onboard/cross_arch_reference > tests/onboard/cross_arch_reference.csv
#include <cstdio>

#include "tests/onboard/cross_arch_cases.hpp"

int main() {
  fnmpc::onboard_testing::WriteCrossArchRows(fnmpc::onboard_testing::ComputeCrossArchRows(),
                                             stdout);
  return 0;
}

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/core/held_for.hpp"

#include <gtest/gtest.h>

namespace fnmpc {
namespace {

TEST(HeldForTest, HoldsOnlyAfterAnUnbrokenRunOfTheDuration) {
  // Times exact in binary, so the comparisons at the boundary are exact.
  HeldFor h;
  EXPECT_FALSE(h.running());
  EXPECT_FALSE(h.For(0.0, 0.0));
  h.Update(true, 1.0);
  h.Update(true, 1.125);  // the run keeps its start
  EXPECT_DOUBLE_EQ(h.since(), 1.0);
  EXPECT_FALSE(h.For(1.125, 0.25));
  EXPECT_TRUE(h.For(1.25, 0.25));
  h.Update(false, 1.375);  // a break ends the run
  EXPECT_FALSE(h.running());
  EXPECT_FALSE(h.For(5.0, 0.25));
  h.Update(true, 2.0);
  EXPECT_FALSE(h.For(2.125, 0.25));
  EXPECT_TRUE(h.For(2.25, 0.25));
}

TEST(HeldForTest, StartKeepsARunningStartAndResetEndsIt) {
  HeldFor h;
  h.Start(3.0);
  h.Start(4.0);
  EXPECT_DOUBLE_EQ(h.since(), 3.0);
  EXPECT_TRUE(h.For(4.0, 1.0));
  h.Reset();
  EXPECT_FALSE(h.running());
  EXPECT_TRUE(std::isnan(h.since()));
  h.Start(4.0);
  EXPECT_FALSE(h.For(4.5, 1.0));
}

}  // namespace
}  // namespace fnmpc

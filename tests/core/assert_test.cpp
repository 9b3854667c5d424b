// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/core/assert.hpp"

#include <gtest/gtest.h>

#include <string>

namespace fnmpc {
namespace {

TEST(AssertTest, DemandThrowsWithConditionFileAndLine) {
  const int horizon = 3;
  try {
    FNMPC_DEMAND(horizon > 5);
    FAIL() << "FNMPC_DEMAND did not throw";
  } catch (const AssertionError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("horizon > 5"), std::string::npos) << what;
    EXPECT_NE(what.find("assert_test.cpp:"), std::string::npos) << what;
  }
  EXPECT_NO_THROW(FNMPC_DEMAND(horizon == 3));
}

TEST(AssertTest, AssertIsArmedExactlyInAssertionBuilds) {
  // Given a condition with a side effect
  int evaluated = 0;
  [[maybe_unused]] auto fails = [&] {
    ++evaluated;
    return false;
  };
  // When FNMPC_ASSERT checks it
  bool threw = false;
  try {
    FNMPC_ASSERT(fails());
  } catch (const AssertionError&) {
    threw = true;
  }
  // Then it is evaluated and throws in Debug (or FNMPC_ENABLE_ASSERTS) builds only
#if !defined(NDEBUG) || defined(FNMPC_ENABLE_ASSERTS)
  EXPECT_EQ(FNMPC_ASSERT_ARMED, 1);
  EXPECT_TRUE(threw);
  EXPECT_EQ(evaluated, 1);
#else
  EXPECT_EQ(FNMPC_ASSERT_ARMED, 0);
  EXPECT_FALSE(threw);
  EXPECT_EQ(evaluated, 0);
#endif
}

}  // namespace
}  // namespace fnmpc

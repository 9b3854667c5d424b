// SPDX-License-Identifier: BSD-3-Clause
// The session and the emulated autopilot allocate nothing per step (the onboard loop).
#include <gtest/gtest.h>

#include "tests/autopilot/link_pair.hpp"
#include "tests/support/malloc_counter.hpp"

namespace fnmpc::autopilot {
namespace {

TEST(AutopilotAllocationTest, HandshakeStreamingAndWatchdogsAllocateNothing) {
  testing::LinkPair link(SessionSettings{}, EmulatedAutopilotSettings{});
  const long mallocs = fnmpc::testing::CountMallocs([&] {
    link.RunUntil(4.0, testing::Hover(), [] { return false; });  // handshake, then streaming
    link.downlink = false;
    link.RunUntil(6.0, testing::Hover(), [] { return false; });  // watchdog hands back
  });
  EXPECT_EQ(mallocs, 0);
  EXPECT_EQ(link.session.state(), SessionState::kHandedBack);
  EXPECT_GT(link.setpoints_seen, 50);
}

}  // namespace
}  // namespace fnmpc::autopilot

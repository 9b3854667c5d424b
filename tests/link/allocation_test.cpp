// SPDX-License-Identifier: BSD-3-Clause
// Sending and polling MAVLink over UDP allocates nothing after construction (the onboard
// control loop runs through these calls every step).
#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <variant>

#include "fnmpc/link/mavlink_connection.hpp"
#include "tests/link/udp_pair.hpp"
#include "tests/support/malloc_counter.hpp"

namespace fnmpc::link {
namespace {

TEST(LinkAllocationTest, SendAndPollAllocateNothing) {
  testing::UdpPair pair;
  MavlinkConnection vehicle(std::move(pair.connect), 1, 191);
  MavlinkConnection autopilot(std::move(pair.listen), 1, 1);
  mavlink::AttitudeQuaternion state;
  mavlink::SetAttitudeTarget setpoint;
  setpoint.q = {1, 0, 0, 0};
  int received = 0;
  auto count = [&](const mavlink::Frame&) { ++received; };
  // The first exchange teaches the listen side its peer (outside the counted part)
  ASSERT_TRUE(vehicle.Send(setpoint));
  autopilot.Poll(1.0, count);
  const long mallocs = fnmpc::testing::CountMallocs([&] {
    for (int i = 0; i < 200; ++i) {
      state.time_boot_ms = static_cast<std::uint32_t>(i);
      autopilot.Send(state);
      vehicle.Poll(0.5, count);
      vehicle.Send(setpoint);
      autopilot.Poll(0.5, count);
    }
  });
  EXPECT_EQ(mallocs, 0);
  EXPECT_EQ(received, 401);
}

}  // namespace
}  // namespace fnmpc::link

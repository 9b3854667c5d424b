// SPDX-License-Identifier: BSD-3-Clause
// MavlinkConnection: frames over a loopback UDP pair, bursts drained in one Poll, signing,
// and garbage between frames counted and dropped.
#include "fnmpc/link/mavlink_connection.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "fnmpc/link/link_address.hpp"
#include "fnmpc/link/transport.hpp"
#include "tests/link/udp_pair.hpp"

namespace fnmpc::link {
namespace {

struct Connections {
  Connections() {
    testing::UdpPair pair;
    vehicle = std::make_unique<MavlinkConnection>(std::move(pair.connect), 1, 191);
    autopilot = std::make_unique<MavlinkConnection>(std::move(pair.listen), 1, 1);
  }
  std::unique_ptr<MavlinkConnection> vehicle;
  std::unique_ptr<MavlinkConnection> autopilot;
};

mavlink::Heartbeat Beat(std::uint32_t custom_mode) {
  mavlink::Heartbeat h;
  h.custom_mode = custom_mode;
  h.type = 2;  // MAV_TYPE_QUADROTOR
  h.mavlink_version = 3;
  return h;
}

std::vector<std::uint32_t> ReceivedModes(MavlinkConnection& c, double timeout) {
  std::vector<std::uint32_t> modes;
  c.Poll(timeout, [&](const mavlink::Frame& f) {
    if (const auto* h = std::get_if<mavlink::Heartbeat>(&f.message))
      modes.push_back(h->custom_mode);
  });
  return modes;
}

TEST(MavlinkConnectionTest, FramesBothWaysWithSenderIdsAndSequenceNumbers) {
  Connections c;
  ASSERT_TRUE(c.vehicle->Send(Beat(7)));
  std::vector<mavlink::FrameHeader> headers;
  c.autopilot->Poll(1.0, [&](const mavlink::Frame& f) { headers.push_back(f.header); });
  ASSERT_EQ(headers.size(), 1u);
  EXPECT_EQ(headers[0].system_id, 1);
  EXPECT_EQ(headers[0].component_id, 191);
  EXPECT_EQ(headers[0].sequence, 0);
  EXPECT_EQ(headers[0].message_id, mavlink::Heartbeat::kId);
  // The listen side replies to the peer whose valid frame it received
  ASSERT_TRUE(c.autopilot->Send(Beat(9)));
  EXPECT_EQ(ReceivedModes(*c.vehicle, 1.0), std::vector<std::uint32_t>{9});
  EXPECT_EQ(c.vehicle->frames_sent(), 1u);
  EXPECT_EQ(c.vehicle->counters().frames_ok, 1u);
  EXPECT_EQ(c.vehicle->send_failures(), 0u);
}

TEST(MavlinkConnectionTest, OnePollDrainsABurst) {
  Connections c;
  for (std::uint32_t i = 0; i < 20; ++i) ASSERT_TRUE(c.vehicle->Send(Beat(i)));
  std::vector<std::uint32_t> expected;
  for (std::uint32_t i = 0; i < 20; ++i) expected.push_back(i);
  EXPECT_EQ(ReceivedModes(*c.autopilot, 1.0), expected);
  EXPECT_TRUE(ReceivedModes(*c.autopilot, 0.0).empty());
}

TEST(MavlinkConnectionTest, SendWithoutAPeerIsCountedNotThrown) {
  Connections c;
  EXPECT_FALSE(c.autopilot->Send(Beat(1)));  // nobody has spoken to the listen side yet
  EXPECT_EQ(c.autopilot->send_failures(), 1u);
  EXPECT_EQ(c.autopilot->frames_sent(), 0u);
}

TEST(MavlinkConnectionTest, SignedFramesPassOnlyWithTheKey) {
  Connections c;
  mavlink::SigningKey key{};
  for (std::size_t i = 0; i < key.size(); ++i) key[i] = static_cast<std::uint8_t>(3 * i + 1);
  c.vehicle->encoder().EnableSigning(key, 0);
  c.autopilot->parser().SetSigningKey(key);
  ASSERT_TRUE(c.vehicle->Send(Beat(5)));
  EXPECT_EQ(ReceivedModes(*c.autopilot, 1.0), std::vector<std::uint32_t>{5});
  mavlink::SigningKey other = key;
  other[0] ^= 0xFF;
  c.autopilot->parser().SetSigningKey(other);
  ASSERT_TRUE(c.vehicle->Send(Beat(6)));
  EXPECT_TRUE(ReceivedModes(*c.autopilot, 1.0).empty());
  EXPECT_EQ(c.autopilot->counters().bad_signatures, 1u);
}

TEST(MavlinkConnectionTest, GarbageBetweenFramesIsCountedAndDropped) {
  testing::UdpPair pair;
  UdpTransport* raw = pair.connect.get();
  MavlinkConnection autopilot(std::move(pair.listen), 1, 1);
  mavlink::Encoder encoder(1, 191);
  std::array<std::uint8_t, mavlink::kMaxFrameLength> frame{};
  const std::size_t n = encoder.Encode(Beat(11), frame);
  std::vector<std::uint8_t> datagram = {0x00, 0xFD, 0x42, 0x13};  // noise, a false start
  datagram.insert(datagram.end(), frame.begin(), frame.begin() + static_cast<long>(n));
  std::vector<std::uint8_t> corrupted(frame.begin(), frame.begin() + static_cast<long>(n));
  corrupted[n - 1] ^= 0x5A;  // wrong checksum
  ASSERT_TRUE(raw->Write(datagram));
  ASSERT_TRUE(raw->Write(corrupted));
  std::vector<std::uint32_t> modes = ReceivedModes(autopilot, 1.0);
  if (modes.empty()) modes = ReceivedModes(autopilot, 1.0);
  EXPECT_EQ(modes, std::vector<std::uint32_t>{11});
  ReceivedModes(autopilot, 0.2);
  EXPECT_EQ(autopilot.counters().frames_ok, 1u);
  EXPECT_GE(autopilot.counters().crc_errors, 1u);
  EXPECT_GE(autopilot.counters().bytes_discarded, 4u);
}

TEST(MavlinkConnectionTest, ListenModeLocksOntoTheExpectedPeerAndIgnoresJunkAndOthers) {
  // Given an onboard computer listening for its flight controller (system 1, component 1)
  testing::UdpPair pair;
  const int port = pair.listen->local_port();
  MavlinkConnection onboard(std::move(pair.listen), 1, 191);
  onboard.ExpectPeer(1, 1);
  MavlinkConnection autopilot(std::move(pair.connect), 1, 1);
  MavlinkConnection bridge(
      OpenTransport(ParseLinkAddress("udpout:127.0.0.1:" + std::to_string(port))), 1, 197);
  const std::unique_ptr<Transport> junk =
      OpenTransport(ParseLinkAddress("udpout:127.0.0.1:" + std::to_string(port)));
  // When junk and the bridge speak first, nobody is answered
  const std::array<std::uint8_t, 6> garbage{0xFD, 0x09, 0x00, 0x00, 0x00, 0x01};
  ASSERT_TRUE(junk->Write(garbage));
  ASSERT_TRUE(bridge.Send(Beat(1)));
  ReceivedModes(onboard, 0.5);
  ReceivedModes(onboard, 0.2);
  EXPECT_FALSE(onboard.Send(Beat(2)));
  // Then the flight controller's frame locks the replies onto it
  ASSERT_TRUE(autopilot.Send(Beat(3)));
  EXPECT_EQ(ReceivedModes(onboard, 1.0), std::vector<std::uint32_t>{3});
  ASSERT_TRUE(onboard.Send(Beat(4)));
  EXPECT_EQ(ReceivedModes(autopilot, 1.0), std::vector<std::uint32_t>{4});
  // And later junk and bridge frames do not redirect them
  ASSERT_TRUE(junk->Write(garbage));
  ASSERT_TRUE(bridge.Send(Beat(5)));
  ReceivedModes(onboard, 0.5);
  ReceivedModes(onboard, 0.2);
  ASSERT_TRUE(onboard.Send(Beat(6)));
  EXPECT_EQ(ReceivedModes(autopilot, 1.0), std::vector<std::uint32_t>{6});
  EXPECT_TRUE(ReceivedModes(bridge, 0.2).empty());
}

}  // namespace
}  // namespace fnmpc::link

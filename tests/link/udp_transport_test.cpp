// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/udp_transport.hpp"

#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

#include "fnmpc/link/transport.hpp"
#include "tests/link/udp_pair.hpp"

namespace fnmpc::link {
namespace {

std::span<const std::uint8_t> Bytes(std::string_view s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

std::string ReadString(Transport& t, double timeout) {
  std::array<std::uint8_t, 512> buffer{};
  const std::size_t n = t.Read(buffer, timeout);
  return std::string(reinterpret_cast<const char*>(buffer.data()), n);
}

TEST(UdpTransportTest, BothDirectionsWithThePeerConfirmedAfterADatagram) {
  testing::UdpPair pair;
  EXPECT_GT(pair.listen->local_port(), 0);
  EXPECT_GT(pair.connect->local_port(), 0);
  // The listen side has nobody to send to before a datagram arrives
  EXPECT_FALSE(pair.listen->has_peer());
  EXPECT_FALSE(pair.listen->Write(Bytes("too early")));
  // Connect -> listen
  ASSERT_TRUE(pair.connect->Write(Bytes("hello")));
  EXPECT_EQ(ReadString(*pair.listen, 1.0), "hello");
  // A datagram alone does not make its sender the peer: only a confirmed one does
  EXPECT_FALSE(pair.listen->has_peer());
  pair.listen->ConfirmLastSender();
  EXPECT_TRUE(pair.listen->has_peer());
  // Listen -> connect, to the learned peer
  ASSERT_TRUE(pair.listen->Write(Bytes("world")));
  EXPECT_EQ(ReadString(*pair.connect, 1.0), "world");
  EXPECT_EQ(pair.listen->datagrams_received(), 1u);
  EXPECT_EQ(pair.connect->datagrams_received(), 1u);
}

TEST(UdpTransportTest, AnUnconfirmedSenderNeverRedirectsTheReplies) {
  testing::UdpPair pair;
  ASSERT_TRUE(pair.connect->Write(Bytes("autopilot")));
  EXPECT_EQ(ReadString(*pair.listen, 1.0), "autopilot");
  pair.listen->ConfirmLastSender();
  // A stranger sends junk to the listen port
  const std::unique_ptr<Transport> stranger = OpenTransport(
      ParseLinkAddress("udpout:127.0.0.1:" + std::to_string(pair.listen->local_port())));
  ASSERT_TRUE(stranger->Write(Bytes("junk")));
  EXPECT_EQ(ReadString(*pair.listen, 1.0), "junk");
  // The reply still goes to the confirmed peer, not the stranger
  ASSERT_TRUE(pair.listen->Write(Bytes("reply")));
  EXPECT_EQ(ReadString(*pair.connect, 1.0), "reply");
  EXPECT_EQ(ReadString(*stranger, 0.2), "");
}

TEST(UdpTransportTest, OneDatagramPerRead) {
  testing::UdpPair pair;
  ASSERT_TRUE(pair.connect->Write(Bytes("first")));
  ASSERT_TRUE(pair.connect->Write(Bytes("second")));
  EXPECT_EQ(ReadString(*pair.listen, 1.0), "first");
  EXPECT_EQ(ReadString(*pair.listen, 1.0), "second");
  EXPECT_EQ(ReadString(*pair.listen, 0.0), "");
}

TEST(UdpTransportTest, ReadTimesOutWithZeroBytes) {
  testing::UdpPair pair;
  std::array<std::uint8_t, 64> buffer{};
  EXPECT_EQ(pair.listen->Read(buffer, 0.0), 0u);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(pair.listen->Read(buffer, 0.05), 0u);
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(elapsed, 2.0);
}

TEST(UdpTransportTest, OpenTransportFromAnAddressWithAHostName) {
  testing::UdpPair pair;
  const std::string text = "udpout:localhost:" + std::to_string(pair.listen->local_port());
  const std::unique_ptr<Transport> t = OpenTransport(ParseLinkAddress(text));
  EXPECT_EQ(t->Describe(), text);
  ASSERT_TRUE(t->Write(Bytes("by name")));
  EXPECT_EQ(ReadString(*pair.listen, 1.0), "by name");
}

TEST(UdpTransportTest, BindErrorNamesTheAddressAndTheErrnoText) {
  testing::UdpPair pair;
  const LinkAddress taken = testing::Udp(LinkAddress::Kind::kUdpListen, pair.listen->local_port());
  try {
    UdpTransport second(taken);
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("link '" + ToString(taken) + "'"), std::string::npos) << message;
    EXPECT_NE(message.find("bind"), std::string::npos) << message;
    EXPECT_NE(message.find("Address already in use"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace fnmpc::link

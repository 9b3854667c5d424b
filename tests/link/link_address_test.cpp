// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/link_address.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace fnmpc::link {
namespace {

TEST(LinkAddressTest, UdpListen) {
  const LinkAddress a = ParseLinkAddress("udp:0.0.0.0:14550");
  EXPECT_EQ(a.kind, LinkAddress::Kind::kUdpListen);
  EXPECT_EQ(a.host, "0.0.0.0");
  EXPECT_EQ(a.port, 14550);
  EXPECT_EQ(a.text, "udp:0.0.0.0:14550");
  EXPECT_EQ(ToString(a), "udp:0.0.0.0:14550");
}

TEST(LinkAddressTest, UdpConnectWithNumericHostOrName) {
  const LinkAddress a = ParseLinkAddress("udpout:127.0.0.1:14540");
  EXPECT_EQ(a.kind, LinkAddress::Kind::kUdpConnect);
  EXPECT_EQ(a.host, "127.0.0.1");
  EXPECT_EQ(a.port, 14540);
  const LinkAddress b = ParseLinkAddress("udpout:px4-sitl.local:65535");
  EXPECT_EQ(b.host, "px4-sitl.local");
  EXPECT_EQ(b.port, 65535);
  EXPECT_EQ(ToString(b), "udpout:px4-sitl.local:65535");
}

TEST(LinkAddressTest, SerialDeviceMayContainColons) {
  const LinkAddress a = ParseLinkAddress("serial:/dev/ttyACM0:921600");
  EXPECT_EQ(a.kind, LinkAddress::Kind::kSerial);
  EXPECT_EQ(a.device, "/dev/ttyACM0");
  EXPECT_EQ(a.baud, 921600);
  const LinkAddress b =
      ParseLinkAddress("serial:/dev/serial/by-path/pci-0000:00:14.0-usb-0:1:1.0:57600");
  EXPECT_EQ(b.device, "/dev/serial/by-path/pci-0000:00:14.0-usb-0:1:1.0");
  EXPECT_EQ(b.baud, 57600);
  EXPECT_EQ(ToString(b), b.text);
}

struct BadAddress {
  const char* text;
  const char* names;  // the part the message must name
};

TEST(LinkAddressTest, EveryErrorQuotesTheAddressNamesThePartAndListsTheForms) {
  const BadAddress cases[] = {
      {"", "missing kind"},
      {":1.2.3.4:5", "missing kind"},
      {"tcp:1.2.3.4:5760", "unknown kind 'tcp'"},
      {"UDP:1.2.3.4:5760", "unknown kind 'UDP'"},
      {"udp", "missing host"},
      {"udp:", "missing host"},
      {"udp:localhost", "missing port"},
      {"udp::14550", "missing host"},
      {"udpout:localhost:", "missing port"},
      {"udpout:localhost:0", "port '0'"},
      {"udpout:localhost:65536", "port '65536'"},
      {"udpout:localhost:-1", "port '-1'"},
      {"udpout:localhost:145x", "port '145x'"},
      {"udpout:localhost: 14550", "port ' 14550'"},
      {"udp:fe80::1:14550", "host 'fe80::1' contains ':'"},
      {"serial", "missing device"},
      {"serial:", "missing device"},
      {"serial:/dev/ttyACM0", "missing baud"},
      {"serial:/dev/ttyACM0:", "missing baud"},
      {"serial::57600", "missing device"},
      {"serial:/dev/ttyACM0:fast", "baud 'fast'"},
      {"serial:/dev/ttyACM0:0", "baud '0'"},
      {"serial:/dev/ttyACM0:-9600", "baud '-9600'"},
  };
  for (const BadAddress& c : cases) {
    SCOPED_TRACE(c.text);
    try {
      ParseLinkAddress(c.text);
      ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("link '" + std::string(c.text) + "'"), std::string::npos) << message;
      EXPECT_NE(message.find(c.names), std::string::npos) << message;
      EXPECT_NE(message.find("expected udp:HOST:PORT, udpout:HOST:PORT or serial:DEVICE:BAUD"),
                std::string::npos)
          << message;
    }
  }
}

}  // namespace
}  // namespace fnmpc::link

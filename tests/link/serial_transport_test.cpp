// SPDX-License-Identifier: BSD-3-Clause
// SerialTransport over a pseudo-terminal pair: the transport opens the pty's slave side by
// path, as it opens /dev/ttyACM0; the test holds the master side (the "flight controller").
#include "fnmpc/link/serial_transport.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>

#include "fnmpc/link/posix_fd.hpp"

namespace fnmpc::link {
namespace {

struct Pty {
  Pty() {
    master = UniqueFd(::posix_openpt(O_RDWR | O_NOCTTY));
    if (master.get() < 0 || ::grantpt(master.get()) != 0 || ::unlockpt(master.get()) != 0) {
      throw std::runtime_error("no pseudo-terminal");
    }
    slave_path = ::ptsname(master.get());
  }
  std::string ReadMaster(double timeout) const {
    pollfd p{master.get(), POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(timeout * 1000)) <= 0) return "";
    std::array<char, 256> buffer{};
    const ssize_t n = ::read(master.get(), buffer.data(), buffer.size());
    return n > 0 ? std::string(buffer.data(), static_cast<std::size_t>(n)) : "";
  }
  UniqueFd master;
  std::string slave_path;
};

LinkAddress Serial(const std::string& device, int baud) {
  LinkAddress a;
  a.kind = LinkAddress::Kind::kSerial;
  a.device = device;
  a.baud = baud;
  a.text = "serial:" + device + ":" + std::to_string(baud);
  return a;
}

std::span<const std::uint8_t> Bytes(std::string_view s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

TEST(SerialTransportTest, BytesBothWaysThroughAPseudoTerminal) {
  Pty pty;
  SerialTransport serial(Serial(pty.slave_path, 921600));
  EXPECT_NE(serial.Describe().find(pty.slave_path), std::string::npos);
  // Raw mode: bytes that a cooked terminal would translate or swallow pass unchanged
  const std::string raw("\x03\x0d\x0a\x11\x13\xfd\x00\x7f", 8);
  ASSERT_TRUE(serial.Write(Bytes(raw)));
  std::string got;
  for (int i = 0; i < 20 && got.size() < raw.size(); ++i) got += pty.ReadMaster(0.5);
  EXPECT_EQ(got, raw);
  ASSERT_EQ(::write(pty.master.get(), raw.data(), raw.size()), static_cast<ssize_t>(raw.size()));
  std::array<std::uint8_t, 64> buffer{};
  std::string back;
  for (int i = 0; i < 20 && back.size() < raw.size(); ++i) {
    const std::size_t n = serial.Read(buffer, 0.5);
    back.append(reinterpret_cast<const char*>(buffer.data()), n);
  }
  EXPECT_EQ(back, raw);
  // Nothing more: a read times out with zero bytes
  EXPECT_EQ(serial.Read(buffer, 0.01), 0u);
}

TEST(SerialTransportTest, UnsupportedBaudListsTheSupportedOnes) {
  Pty pty;
  try {
    SerialTransport serial(Serial(pty.slave_path, 12345));
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("12345"), std::string::npos) << message;
    EXPECT_NE(message.find("921600"), std::string::npos) << message;
    EXPECT_NE(message.find("57600"), std::string::npos) << message;
  }
  const auto bauds = SupportedBauds();
  EXPECT_TRUE(std::is_sorted(bauds.begin(), bauds.end()));
}

TEST(SerialTransportTest, MissingDeviceNamesTheDeviceAndTheErrnoText) {
  try {
    SerialTransport serial(Serial("/dev/fnmpc-no-such-device", 57600));
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("/dev/fnmpc-no-such-device"), std::string::npos) << message;
    EXPECT_NE(message.find("No such file or directory"), std::string::npos) << message;
  }
}

TEST(SerialTransportTest, HangUpIsAnErrorNotAnEndlessStreamOfEmptyReads) {
  auto pty = std::make_unique<Pty>();
  SerialTransport serial(Serial(pty->slave_path, 115200));
  pty.reset();  // the master closes: the "flight controller" is unplugged
  std::array<std::uint8_t, 64> buffer{};
  EXPECT_THROW(serial.Read(buffer, 0.5), std::runtime_error);
}

}  // namespace
}  // namespace fnmpc::link

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/serial_transport.hpp"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <stdexcept>
#include <utility>

namespace fnmpc::link {
namespace {

constexpr std::array<std::pair<int, speed_t>, 14> kBauds{{
    {9600, B9600},
    {19200, B19200},
    {38400, B38400},
    {57600, B57600},
    {115200, B115200},
    {230400, B230400},
    {460800, B460800},
    {500000, B500000},
    {576000, B576000},
    {921600, B921600},
    {1000000, B1000000},
    {1500000, B1500000},
    {2000000, B2000000},
    {3000000, B3000000},
}};

constexpr std::array<int, kBauds.size()> kBaudValues = [] {
  std::array<int, kBauds.size()> v{};
  for (std::size_t i = 0; i < kBauds.size(); ++i) v[i] = kBauds[i].first;
  return v;
}();

speed_t SpeedOf(const LinkAddress& a, const std::string& link) {
  for (const auto& [baud, speed] : kBauds) {
    if (baud == a.baud) return speed;
  }
  std::string list;
  for (const int b : kBaudValues) list += (list.empty() ? "" : " ") + std::to_string(b);
  throw std::invalid_argument("link '" + link + "': unsupported baud " + std::to_string(a.baud) +
                              "; supported: " + list);
}

}  // namespace

std::span<const int> SupportedBauds() { return kBaudValues; }

SerialTransport::SerialTransport(const LinkAddress& address) : description_(ToString(address)) {
  if (address.kind != LinkAddress::Kind::kSerial) {
    throw std::invalid_argument("link '" + description_ + "': not a serial address");
  }
  const speed_t speed = SpeedOf(address, description_);
  fd_ = UniqueFd(::open(address.device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
  if (fd_.get() < 0) {
    throw std::runtime_error(ErrnoMessage(description_, "open " + address.device, errno));
  }
  termios t{};
  if (::tcgetattr(fd_.get(), &t) != 0) {
    throw std::runtime_error(ErrnoMessage(description_, "tcgetattr " + address.device, errno));
  }
  ::cfmakeraw(&t);  // no echo, no line editing, no signals, no CR/LF mapping, 8 data bits
  t.c_cflag &= ~static_cast<tcflag_t>(PARENB | CSTOPB | CSIZE | CRTSCTS);  // no parity, 1 stop
  t.c_cflag |= CS8 | CLOCAL | CREAD;  // ignore modem lines, enable the receiver
  t.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);  // no software flow control
  t.c_cc[VMIN] = 0;
  t.c_cc[VTIME] = 0;
  if (::cfsetispeed(&t, speed) != 0 || ::cfsetospeed(&t, speed) != 0 ||
      ::tcsetattr(fd_.get(), TCSANOW, &t) != 0) {
    throw std::runtime_error(ErrnoMessage(description_, "configure " + address.device, errno));
  }
  if (::tcflush(fd_.get(), TCIFLUSH) != 0) {
    throw std::runtime_error(ErrnoMessage(description_, "tcflush " + address.device, errno));
  }
}

std::size_t SerialTransport::Read(std::span<std::uint8_t> buffer, double timeout) {
  short revents = POLLIN;
  if (timeout > 0.0) revents = WaitFd(fd_.get(), POLLIN, timeout, description_);
  if (revents == 0) return 0;
  for (;;) {
    const ssize_t got = ::read(fd_.get(), buffer.data(), buffer.size());
    if (got > 0) return static_cast<std::size_t>(got);
    if (got == 0) {
      // Readable with nothing to read: the device hung up.
      if ((revents & (POLLHUP | POLLERR)) != 0) {
        throw std::runtime_error("link '" + description_ + "': device hung up");
      }
      return 0;
    }
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
    throw std::runtime_error(ErrnoMessage(description_, "read", errno));
  }
}

bool SerialTransport::Write(std::span<const std::uint8_t> bytes) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline =
      Clock::now() +
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(kWriteTimeout));
  while (!bytes.empty()) {
    const ssize_t put = ::write(fd_.get(), bytes.data(), bytes.size());
    if (put > 0) {
      bytes = bytes.subspan(static_cast<std::size_t>(put));
      continue;
    }
    if (put < 0 && errno == EINTR) continue;
    if (put < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
      throw std::runtime_error(ErrnoMessage(description_, "write", errno));
    }
    const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
    if (left <= 0.0) return false;
    const short revents = WaitFd(fd_.get(), POLLOUT, left, description_);
    if ((revents & (POLLHUP | POLLERR)) != 0 && (revents & POLLOUT) == 0) {
      throw std::runtime_error("link '" + description_ + "': device hung up");
    }
  }
  return true;
}

}  // namespace fnmpc::link

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/posix_fd.hpp"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <system_error>

namespace fnmpc::link {

UniqueFd& UniqueFd::operator=(UniqueFd&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = other.release();
  }
  return *this;
}

UniqueFd::~UniqueFd() {
  if (fd_ >= 0) ::close(fd_);
}

int UniqueFd::release() {
  const int fd = fd_;
  fd_ = -1;
  return fd;
}

short WaitFd(int fd, short events, double timeout, const std::string& link) {
  using Clock = std::chrono::steady_clock;
  const bool wait = timeout > 0.0;
  const Clock::time_point deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double>(wait ? timeout : 0.0));
  for (;;) {
    int ms = 0;
    if (wait) {
      const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
      // Rounded up, so that a short wait is not a busy loop of poll(0).
      ms = left > 0.0 ? static_cast<int>(std::min(std::ceil(left * 1e3), 2e9)) : 0;
    }
    pollfd p{fd, events, 0};
    const int n = ::poll(&p, 1, ms);
    if (n > 0) return p.revents;
    if (n == 0) return 0;
    if (errno != EINTR) throw std::runtime_error(ErrnoMessage(link, "poll", errno));
  }
}

std::string ErrnoMessage(std::string_view link, std::string_view what, int error) {
  return "link '" + std::string(link) + "': " + std::string(what) + ": " +
         std::generic_category().message(error);
}

}  // namespace fnmpc::link

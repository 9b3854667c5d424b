// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <string_view>

/// POSIX helpers of the transports: an owned file descriptor, waiting with poll(), errors.
namespace fnmpc::link {

/// Owns a file descriptor (closed on destruction); -1 when empty. Move-only.
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  UniqueFd(UniqueFd&& other) noexcept : fd_(other.release()) {}
  UniqueFd& operator=(UniqueFd&& other) noexcept;
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  ~UniqueFd();

  [[nodiscard]] int get() const { return fd_; }
  int release();

 private:
  int fd_ = -1;
};

/// Waits up to `timeout` [s] (0 or less: does not wait) until `fd` has one of `events`
/// (POLLIN, POLLOUT) or an error or hang-up; returns poll's revents, 0 on timeout. EINTR is
/// retried with the remaining time. Throws std::runtime_error naming `link` on a poll error.
short WaitFd(int fd, short events, double timeout, const std::string& link);

/// "link 'LINK': WHAT: <strerror(error)>", for std::runtime_error.
std::string ErrnoMessage(std::string_view link, std::string_view what, int error);

}  // namespace fnmpc::link

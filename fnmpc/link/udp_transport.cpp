// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/udp_transport.hpp"

#include <arpa/inet.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>

#include <cerrno>
#include <stdexcept>

namespace fnmpc::link {
namespace {

// host:port as an IPv4 socket address: numeric, else through the resolver.
sockaddr_in Resolve(const LinkAddress& a, const std::string& link) {
  sockaddr_in s{};
  s.sin_family = AF_INET;
  s.sin_port = htons(static_cast<std::uint16_t>(a.port));
  if (::inet_pton(AF_INET, a.host.c_str(), &s.sin_addr) == 1) return s;
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  const int rc = ::getaddrinfo(a.host.c_str(), nullptr, &hints, &found);
  if (rc != 0 || found == nullptr) {
    const std::string why = rc == EAI_SYSTEM ? ErrnoMessage(link, "resolve", errno)
                                             : "link '" + link + "': cannot resolve host '" +
                                                   a.host + "': " + ::gai_strerror(rc);
    throw std::runtime_error(why);
  }
  s.sin_addr = reinterpret_cast<const sockaddr_in*>(found->ai_addr)->sin_addr;
  ::freeaddrinfo(found);
  return s;
}

bool Transient(int error) {
  switch (error) {
    case EAGAIN:
#if EWOULDBLOCK != EAGAIN
    case EWOULDBLOCK:
#endif
    case ENOBUFS:
    case ECONNREFUSED:
    case ENETUNREACH:
    case EHOSTUNREACH:
    case ENETDOWN:
    case EHOSTDOWN:
      return true;
    default:
      return false;
  }
}

}  // namespace

UdpTransport::UdpTransport(const LinkAddress& address)
    : description_(ToString(address)), listen_(address.kind == LinkAddress::Kind::kUdpListen) {
  if (address.kind == LinkAddress::Kind::kSerial) {
    throw std::invalid_argument("link '" + description_ + "': not a UDP address");
  }
  const sockaddr_in target = Resolve(address, description_);
  fd_ = UniqueFd(::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (fd_.get() < 0) throw std::runtime_error(ErrnoMessage(description_, "socket", errno));
  sockaddr_in local{};
  local.sin_family = AF_INET;
  local.sin_addr.s_addr = htonl(INADDR_ANY);
  if (listen_) {
    local = target;
  } else {
    peer_ = target;
    has_peer_ = true;
  }
  if (::bind(fd_.get(), reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
    throw std::runtime_error(ErrnoMessage(description_, "bind", errno));
  }
  socklen_t length = sizeof local;
  if (::getsockname(fd_.get(), reinterpret_cast<sockaddr*>(&local), &length) != 0) {
    throw std::runtime_error(ErrnoMessage(description_, "getsockname", errno));
  }
  local_port_ = ntohs(local.sin_port);
}

bool UdpTransport::Receive(std::span<std::uint8_t> buffer, std::size_t* n) {
  for (;;) {
    sockaddr_in from{};
    socklen_t length = sizeof from;
    const ssize_t got = ::recvfrom(fd_.get(), buffer.data(), buffer.size(), 0,
                                   reinterpret_cast<sockaddr*>(&from), &length);
    if (got >= 0) {
      *n = static_cast<std::size_t>(got);  // a longer datagram is truncated to the buffer
      ++datagrams_received_;
      last_sender_ = from;
      return true;
    }
    if (errno == EINTR) continue;
    if (Transient(errno)) return false;
    throw std::runtime_error(ErrnoMessage(description_, "recvfrom", errno));
  }
}

void UdpTransport::ConfirmLastSender() {
  if (!listen_ || last_sender_.sin_family != AF_INET) return;
  peer_ = last_sender_;
  has_peer_ = true;
}

std::size_t UdpTransport::Read(std::span<std::uint8_t> buffer, double timeout) {
  std::size_t n = 0;
  if (Receive(buffer, &n)) return n;
  if (timeout <= 0.0 || WaitFd(fd_.get(), POLLIN, timeout, description_) == 0) return 0;
  Receive(buffer, &n);
  return n;
}

bool UdpTransport::Write(std::span<const std::uint8_t> bytes) {
  if (!has_peer_) return false;
  for (;;) {
    const ssize_t sent = ::sendto(fd_.get(), bytes.data(), bytes.size(), 0,
                                  reinterpret_cast<const sockaddr*>(&peer_), sizeof peer_);
    if (sent >= 0) return static_cast<std::size_t>(sent) == bytes.size();
    if (errno == EINTR) continue;
    if (Transient(errno)) return false;
    throw std::runtime_error(ErrnoMessage(description_, "sendto", errno));
  }
}

}  // namespace fnmpc::link

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/link_address.hpp"

#include <charconv>
#include <stdexcept>
#include <system_error>

namespace fnmpc::link {
namespace {

constexpr std::string_view kForms =
    "expected udp:HOST:PORT, udpout:HOST:PORT or serial:DEVICE:BAUD";

[[noreturn]] void Fail(std::string_view text, std::string_view what) {
  throw std::invalid_argument("link '" + std::string(text) + "': " + std::string(what) + "; " +
                              std::string(kForms));
}

// Reads a decimal integer in [min, max] into *value; false when `s` is not one.
bool ParseInt(std::string_view s, int min, int max, int* value) {
  if (s.empty()) return false;
  int v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc{} || end != s.data() + s.size() || v < min || v > max) return false;
  *value = v;
  return true;
}

void ParseUdp(std::string_view text, std::string_view rest, LinkAddress* a) {
  const std::size_t colon = rest.find(':');
  if (colon == std::string_view::npos) Fail(text, rest.empty() ? "missing host" : "missing port");
  const std::string_view host = rest.substr(0, colon);
  const std::string_view port = rest.substr(colon + 1);
  if (host.empty()) Fail(text, "missing host");
  if (port.empty()) Fail(text, "missing port");
  if (port.find(':') != std::string_view::npos) {
    Fail(text, "host '" + std::string(rest.substr(0, rest.rfind(':'))) +
                   "' contains ':' (IPv6 is not supported)");
  }
  if (!ParseInt(port, 1, 65535, &a->port)) {
    Fail(text, "port '" + std::string(port) + "' is not an integer in 1..65535");
  }
  a->host = std::string(host);
}

void ParseSerial(std::string_view text, std::string_view rest, LinkAddress* a) {
  const std::size_t colon = rest.rfind(':');
  if (colon == std::string_view::npos) Fail(text, rest.empty() ? "missing device" : "missing baud");
  const std::string_view device = rest.substr(0, colon);
  const std::string_view baud = rest.substr(colon + 1);
  if (device.empty()) Fail(text, "missing device");
  if (baud.empty()) Fail(text, "missing baud");
  if (!ParseInt(baud, 1, 100'000'000, &a->baud)) {
    Fail(text, "baud '" + std::string(baud) + "' is not a positive integer");
  }
  a->device = std::string(device);
}

}  // namespace

LinkAddress ParseLinkAddress(std::string_view text) {
  LinkAddress a;
  a.text = std::string(text);
  const std::size_t colon = text.find(':');
  const std::string_view scheme = text.substr(0, colon);
  const std::string_view rest =
      colon == std::string_view::npos ? std::string_view{} : text.substr(colon + 1);
  if (scheme == "udp") {
    a.kind = LinkAddress::Kind::kUdpListen;
  } else if (scheme == "udpout") {
    a.kind = LinkAddress::Kind::kUdpConnect;
  } else if (scheme == "serial") {
    a.kind = LinkAddress::Kind::kSerial;
  } else {
    Fail(text, scheme.empty() ? "missing kind" : "unknown kind '" + std::string(scheme) + "'");
  }
  if (colon == std::string_view::npos) {
    Fail(text, a.kind == LinkAddress::Kind::kSerial ? "missing device" : "missing host");
  }
  if (a.kind == LinkAddress::Kind::kSerial) {
    ParseSerial(text, rest, &a);
  } else {
    ParseUdp(text, rest, &a);
  }
  return a;
}

std::string ToString(const LinkAddress& address) {
  switch (address.kind) {
    case LinkAddress::Kind::kUdpListen:
      return "udp:" + address.host + ":" + std::to_string(address.port);
    case LinkAddress::Kind::kUdpConnect:
      return "udpout:" + address.host + ":" + std::to_string(address.port);
    case LinkAddress::Kind::kSerial:
      return "serial:" + address.device + ":" + std::to_string(address.baud);
  }
  return address.text;
}

}  // namespace fnmpc::link

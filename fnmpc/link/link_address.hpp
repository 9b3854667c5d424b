// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <string_view>

/// Link addresses: where the MAVLink stream to the flight controller runs.
namespace fnmpc::link {

/// A parsed link address (ParseLinkAddress).
struct LinkAddress {
  enum class Kind {
    kUdpListen,   ///< "udp:HOST:PORT": bind HOST:PORT, reply to the last sender
    kUdpConnect,  ///< "udpout:HOST:PORT": send to HOST:PORT from an ephemeral local port
    kSerial,      ///< "serial:DEVICE:BAUD": a serial device
  };
  Kind kind = Kind::kUdpConnect;
  std::string host;    ///< UDP: numeric IPv4 address or host name
  int port = 0;        ///< UDP port, 1..65535
  std::string device;  ///< serial device path, e.g. /dev/ttyACM0
  int baud = 0;        ///< serial baud rate
  std::string text;    ///< the address as given
};

/// Parses "udp:HOST:PORT" (bind HOST:PORT, e.g. 0.0.0.0:14550, and reply to whoever sent the
/// last datagram), "udpout:HOST:PORT" (send to HOST:PORT from an ephemeral local port and
/// receive the replies there) or "serial:DEVICE:BAUD". HOST must not contain ':' (IPv4 or a
/// host name; names are resolved when the transport is opened). DEVICE may contain ':' (as
/// /dev/serial/by-path names do): the baud is the part after the last ':'. The baud must be
/// a positive integer here; whether the device supports it is checked when it is opened.
/// Throws std::invalid_argument whose message quotes the address, names the wrong part and
/// lists the accepted forms.
LinkAddress ParseLinkAddress(std::string_view text);

/// The canonical text of `address`, e.g. "udpout:127.0.0.1:14540" (for logs).
std::string ToString(const LinkAddress& address);

}  // namespace fnmpc::link

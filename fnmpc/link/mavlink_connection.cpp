// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/link/mavlink_connection.hpp"

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <utility>

namespace fnmpc::link {

MavlinkConnection::MavlinkConnection(std::unique_ptr<Transport> transport, std::uint8_t system_id,
                                     std::uint8_t component_id)
    : transport_(std::move(transport)), encoder_(system_id, component_id) {
  if (!transport_) throw std::invalid_argument("MavlinkConnection: no transport");
}

void MavlinkConnection::EnableSigning(const mavlink::SigningKey& key, std::uint8_t link_id) {
  encoder_.EnableSigning(key, link_id);
  parser_.SetSigningKey(key);
  UpdateSigningTime();
}

void MavlinkConnection::UpdateSigningTime() {
  if (!encoder_.signing()) return;
  const auto unix_us = std::chrono::duration_cast<std::chrono::microseconds>(
                           std::chrono::system_clock::now().time_since_epoch())
                           .count();
  const std::uint64_t t = mavlink::SigningTimestampFromUnixUs(
      static_cast<std::uint64_t>(std::max<std::int64_t>(unix_us, 0)));
  encoder_.SetTimestamp(t);
  parser_.SetTimestamp(t);
}

bool MavlinkConnection::Send(const mavlink::Message& message) {
  UpdateSigningTime();
  const std::size_t n = encoder_.Encode(message, frame_buffer_);
  const bool sent =
      n > 0 && transport_->Write(std::span<const std::uint8_t>(frame_buffer_.data(), n));
  ++(sent ? frames_sent_ : send_failures_);
  return sent;
}

bool MavlinkConnection::SendOther(std::uint32_t message_id, std::uint8_t crc_extra,
                                  std::span<const std::uint8_t> payload) {
  UpdateSigningTime();
  const std::size_t n = encoder_.EncodePayload(message_id, crc_extra, payload, frame_buffer_);
  const bool sent =
      n > 0 && transport_->Write(std::span<const std::uint8_t>(frame_buffer_.data(), n));
  ++(sent ? frames_sent_ : send_failures_);
  return sent;
}

}  // namespace fnmpc::link

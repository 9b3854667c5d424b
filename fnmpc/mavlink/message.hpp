// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <variant>

#include "fnmpc/mavlink/messages.hpp"
#include "fnmpc/mavlink/protocol.hpp"

/// Any supported message (a std::variant over the structs of messages.hpp), the table of
/// their ids, names, CRC_EXTRA and lengths, and packing by id.
namespace fnmpc::mavlink {

/// One of the supported messages.
using Message = std::variant<Heartbeat, SysStatus, BatteryStatus, Attitude, AttitudeQuaternion,
                             LocalPositionNed, Odometry, HighresImu, SetAttitudeTarget,
                             AttitudeTarget, CommandLong, CommandAck, FnmpcRelativeObservation>;

/// Number of supported messages.
inline constexpr std::size_t kNumMessages = std::variant_size_v<Message>;

/// What the framing needs to know of a message.
struct MessageInfo {
  std::uint32_t id = 0;           ///< message id
  std::string_view name;          ///< MAVLink name, e.g. "HEARTBEAT"
  std::uint8_t crc_extra = 0;     ///< CRC_EXTRA
  std::size_t min_length = 0;     ///< base payload length [bytes]
  std::size_t max_length = 0;     ///< payload length with extensions [bytes]
  std::size_t variant_index = 0;  ///< index of the struct in Message
  /// "common" (common.xml) or the dialect a struct states as kDialect ("fnmpc").
  std::string_view dialect = "common";
};

/// The supported messages, in the order of Message's alternatives.
std::span<const MessageInfo> SupportedMessages();

/// The message with id `id`, or nullptr when it is not supported.
const MessageInfo* FindMessageInfo(std::uint32_t id);

/// The table entry of the message held by `message`.
const MessageInfo& InfoOf(const Message& message);

/// Writes the full (untruncated) payload of `message` into `out`; returns its length, the
/// message's max_length.
std::size_t PackPayload(const Message& message, std::span<std::uint8_t, kMaxPayloadLength> out);

/// Decodes the payload of message `id` into *message; a payload shorter than the message's
/// max_length (truncated, or without extensions) reads as zero-extended, bytes beyond
/// max_length are ignored. Returns false (and leaves *message) when `id` is not supported.
bool UnpackPayload(std::uint32_t id, std::span<const std::uint8_t> payload, Message* message);

}  // namespace fnmpc::mavlink

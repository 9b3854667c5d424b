// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/message.hpp"

#include <array>
#include <utility>

#include "fnmpc/mavlink/message_layout.hpp"

namespace fnmpc::mavlink {
namespace {

template <class M>
constexpr std::string_view DialectOf() {
  if constexpr (requires { M::kDialect; }) {
    return M::kDialect;
  } else {
    return "common";
  }
}

template <std::size_t... I>
constexpr std::array<MessageInfo, kNumMessages> MakeTable(std::index_sequence<I...>) {
  return {MessageInfo{std::variant_alternative_t<I, Message>::kId,
                      std::variant_alternative_t<I, Message>::kName,
                      std::variant_alternative_t<I, Message>::kCrcExtra,
                      std::variant_alternative_t<I, Message>::kMinLength,
                      std::variant_alternative_t<I, Message>::kMaxLength, I,
                      DialectOf<std::variant_alternative_t<I, Message>>()}...};
}

constexpr std::array<MessageInfo, kNumMessages> kTable =
    MakeTable(std::make_index_sequence<kNumMessages>());

template <std::size_t... I>
constexpr bool AllLayoutsMatch(std::index_sequence<I...>) {
  return (LayoutMatches<std::variant_alternative_t<I, Message>>() && ...);
}
// Every struct's CRC_EXTRA, lengths and field order agree with its field list.
static_assert(AllLayoutsMatch(std::make_index_sequence<kNumMessages>()),
              "a message struct's constants disagree with its fields (message_layout.hpp)");

constexpr bool IdsUnique() {
  for (std::size_t a = 0; a < kNumMessages; ++a) {
    for (std::size_t b = a + 1; b < kNumMessages; ++b) {
      if (kTable[a].id == kTable[b].id) return false;
    }
  }
  return true;
}
static_assert(IdsUnique(), "two message structs share an id");

template <std::size_t I>
void UnpackAs(std::span<const std::uint8_t> payload, Message* message) {
  using M = std::variant_alternative_t<I, Message>;
  message->template emplace<I>(UnpackPayload<M>(payload));
}

template <std::size_t... I>
constexpr std::array<void (*)(std::span<const std::uint8_t>, Message*), kNumMessages> MakeUnpackers(
    std::index_sequence<I...>) {
  return {&UnpackAs<I>...};
}

constexpr auto kUnpackers = MakeUnpackers(std::make_index_sequence<kNumMessages>());

}  // namespace

std::span<const MessageInfo> SupportedMessages() { return kTable; }

const MessageInfo* FindMessageInfo(std::uint32_t id) {
  for (const MessageInfo& info : kTable) {
    if (info.id == id) return &info;
  }
  return nullptr;
}

const MessageInfo& InfoOf(const Message& message) { return kTable[message.index()]; }

std::size_t PackPayload(const Message& message, std::span<std::uint8_t, kMaxPayloadLength> out) {
  return std::visit(
      [&](const auto& m) {
        using M = std::decay_t<decltype(m)>;
        PackPayload(m, out.template first<M::kMaxLength>());
        return M::kMaxLength;
      },
      message);
}

bool UnpackPayload(std::uint32_t id, std::span<const std::uint8_t> payload, Message* message) {
  const MessageInfo* info = FindMessageInfo(id);
  if (info == nullptr) return false;
  kUnpackers[info->variant_index](payload, message);
  return true;
}

}  // namespace fnmpc::mavlink

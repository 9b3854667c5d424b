// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/mavlink/encoder.hpp"

#include <array>
#include <cstring>

#include "fnmpc/mavlink/crc.hpp"
#include "fnmpc/mavlink/wire.hpp"

namespace fnmpc::mavlink {

std::size_t WriteFrame(const FrameSpec& spec, std::span<const std::uint8_t> payload,
                       std::span<std::uint8_t> out) {
  const bool sign = spec.key != nullptr;
  const std::size_t length =
      kHeaderLength + payload.size() + kChecksumLength + (sign ? kSignatureLength : 0);
  if (payload.size() > kMaxPayloadLength || spec.message_id >= (1U << 24) ||
      spec.timestamp > kMaxSigningTimestamp || out.size() < length) {
    return 0;
  }
  std::uint8_t* p = out.data();
  p[0] = kStartByte;
  p[1] = static_cast<std::uint8_t>(payload.size());
  p[2] = sign ? kIncompatFlagSigned : 0;
  p[3] = spec.compat_flags;
  p[4] = spec.sequence;
  p[5] = spec.system_id;
  p[6] = spec.component_id;
  wire::PutUint(p + 7, spec.message_id, 3);
  if (!payload.empty()) std::memcpy(p + kHeaderLength, payload.data(), payload.size());
  const std::size_t crc_at = kHeaderLength + payload.size();
  std::uint16_t crc = CrcAccumulate(std::span<const std::uint8_t>(p + 1, crc_at - 1));
  crc = CrcAccumulate(spec.crc_extra, crc);
  wire::Put(p + crc_at, crc);
  if (sign) {
    const std::size_t sig_at = crc_at + kChecksumLength;
    p[sig_at] = spec.link_id;
    wire::PutUint(p + sig_at + 1, spec.timestamp, 6);
    const auto signature = ComputeSignature(*spec.key, std::span<const std::uint8_t>(p, sig_at),
                                            spec.link_id, spec.timestamp);
    std::memcpy(p + sig_at + 7, signature.data(), signature.size());
  }
  return length;
}

Encoder::Encoder(std::uint8_t system_id, std::uint8_t component_id)
    : system_id_(system_id), component_id_(component_id) {}

void Encoder::EnableSigning(const SigningKey& key, std::uint8_t link_id) {
  key_ = key;
  link_id_ = link_id;
  signing_ = true;
}

void Encoder::DisableSigning() {
  key_.fill(0);
  signing_ = false;
}

std::size_t Encoder::Encode(const Message& message, std::span<std::uint8_t> out) {
  std::array<std::uint8_t, kMaxPayloadLength> payload{};
  const std::size_t full = PackPayload(message, payload);
  const MessageInfo& info = InfoOf(message);
  return EncodePayload(info.id, info.crc_extra, std::span<const std::uint8_t>(payload.data(), full),
                       out);
}

std::size_t Encoder::EncodePayload(std::uint32_t message_id, std::uint8_t crc_extra,
                                   std::span<const std::uint8_t> payload,
                                   std::span<std::uint8_t> out) {
  const std::size_t length = TruncatedPayloadLength(payload);
  FrameSpec spec;
  spec.sequence = sequence_;
  spec.system_id = system_id_;
  spec.component_id = component_id_;
  spec.message_id = message_id;
  spec.crc_extra = crc_extra;
  std::uint64_t timestamp = 0;
  if (signing_) {
    timestamp = signed_any_ && clock_ <= last_timestamp_ ? last_timestamp_ + 1 : clock_;
    spec.key = &key_;
    spec.link_id = link_id_;
    spec.timestamp = timestamp;
  }
  const std::size_t written = WriteFrame(spec, payload.first(length), out);
  if (written == 0) return 0;
  ++sequence_;
  if (signing_) {
    last_timestamp_ = timestamp;
    signed_any_ = true;
  }
  return written;
}

}  // namespace fnmpc::mavlink

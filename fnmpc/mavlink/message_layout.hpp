// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <type_traits>

#include "fnmpc/mavlink/crc.hpp"
#include "fnmpc/mavlink/wire.hpp"

/// What the message structs of messages.hpp have in common, and what is derived from their
/// field lists.
///
/// A message struct M declares its members in wire order and lists them once, in
///
///   template <class Self, class V> static constexpr void VisitFields(Self& m, V& v) {
///     v.Field("custom_mode", m.custom_mode);   // base fields: sorted by type size
///     v.Extension("time_remaining", m.time_remaining);  // extensions: XML order, last
///   }
///
/// with the field's MAVLink name. From that list this header derives the wire layout:
/// Pack/Unpack, the base and full payload lengths, and CRC_EXTRA, so that the constants each
/// struct states (kCrcExtra, kMinLength, kMaxLength, copied from common.xml's generated
/// values) are checked at compile time against its fields (messages.cpp): a misspelt name, a
/// wrong type or array length, or a field out of wire order fails the build.
namespace fnmpc::mavlink {

/// MAVLink's name of a field type, as it enters CRC_EXTRA.
template <class T>
constexpr std::string_view FieldTypeName() {
  if constexpr (std::is_same_v<T, std::uint8_t>) return "uint8_t";
  if constexpr (std::is_same_v<T, std::int8_t>) return "int8_t";
  if constexpr (std::is_same_v<T, std::uint16_t>) return "uint16_t";
  if constexpr (std::is_same_v<T, std::int16_t>) return "int16_t";
  if constexpr (std::is_same_v<T, std::uint32_t>) return "uint32_t";
  if constexpr (std::is_same_v<T, std::int32_t>) return "int32_t";
  if constexpr (std::is_same_v<T, std::uint64_t>) return "uint64_t";
  if constexpr (std::is_same_v<T, std::int64_t>) return "int64_t";
  if constexpr (std::is_same_v<T, float>) return "float";
  if constexpr (std::is_same_v<T, double>) return "double";
  if constexpr (std::is_same_v<T, char>) return "char";
}

namespace internal {

template <class T>
struct FieldShape {
  using Element = T;
  static constexpr std::size_t kCount = 0;  // 0: not an array
};
template <class T, std::size_t N>
struct FieldShape<std::array<T, N>> {
  using Element = T;
  static constexpr std::size_t kCount = N;
};

// CRC_EXTRA (mavgen): the CRC of "NAME " and, for each base field in wire order,
// "type name " followed by the array length as one byte for arrays; the high and low bytes of
// the result XORed. Extensions do not enter it.
struct CrcExtraVisitor {
  std::uint16_t crc = kCrcInit;
  template <class T>
  constexpr void Field(std::string_view name, const T& /*value*/) {
    using Shape = FieldShape<T>;
    crc = CrcAccumulate(FieldTypeName<typename Shape::Element>(), crc);
    crc = CrcAccumulate(std::string_view(" "), crc);
    crc = CrcAccumulate(name, crc);
    crc = CrcAccumulate(std::string_view(" "), crc);
    if constexpr (Shape::kCount > 0)
      crc = CrcAccumulate(static_cast<std::uint8_t>(Shape::kCount), crc);
  }
  template <class T>
  constexpr void Extension(std::string_view /*name*/, const T& /*value*/) {}
};

// Payload lengths, and whether the base fields are in wire order (non-increasing element size).
struct LengthVisitor {
  std::size_t base = 0;
  std::size_t total = 0;
  std::size_t last_element_size = 8;
  bool sorted = true;
  bool extension_seen = false;
  bool base_after_extension = false;
  template <class T>
  constexpr void Field(std::string_view /*name*/, const T& /*value*/) {
    constexpr std::size_t element = sizeof(typename FieldShape<T>::Element);
    if (element > last_element_size) sorted = false;
    if (extension_seen) base_after_extension = true;
    last_element_size = element;
    base += sizeof(T);
    total += sizeof(T);
  }
  template <class T>
  constexpr void Extension(std::string_view /*name*/, const T& /*value*/) {
    extension_seen = true;
    total += sizeof(T);
  }
};

struct PackVisitor {
  std::uint8_t* out;
  template <class T>
  constexpr void Field(std::string_view /*name*/, const T& value) {
    out = wire::Put(out, value);
  }
  template <class T>
  constexpr void Extension(std::string_view /*name*/, const T& value) {
    out = wire::Put(out, value);
  }
};

struct UnpackVisitor {
  const std::uint8_t* in;
  template <class T>
  constexpr void Field(std::string_view /*name*/, T& value) {
    in = wire::Get(in, &value);
  }
  template <class T>
  constexpr void Extension(std::string_view /*name*/, T& value) {
    in = wire::Get(in, &value);
  }
};

}  // namespace internal

/// CRC_EXTRA of message M computed from its field list.
template <class M>
constexpr std::uint8_t ComputeCrcExtra() {
  internal::CrcExtraVisitor v;
  v.crc = CrcAccumulate(M::kName, v.crc);
  v.crc = CrcAccumulate(std::string_view(" "), v.crc);
  const M m{};
  M::VisitFields(m, v);
  return static_cast<std::uint8_t>((v.crc & 0xFFU) ^ (v.crc >> 8));
}

/// Payload length of M's base fields (the MAVLink 1 length) from its field list [bytes].
template <class M>
constexpr std::size_t ComputeMinLength() {
  internal::LengthVisitor v;
  const M m{};
  M::VisitFields(m, v);
  return v.base;
}

/// Payload length of M with its extensions from its field list [bytes].
template <class M>
constexpr std::size_t ComputeMaxLength() {
  internal::LengthVisitor v;
  const M m{};
  M::VisitFields(m, v);
  return v.total;
}

/// True when M lists its base fields in wire order (element sizes non-increasing) and its
/// extensions after them.
template <class M>
constexpr bool FieldsInWireOrder() {
  internal::LengthVisitor v;
  const M m{};
  M::VisitFields(m, v);
  return v.sorted && !v.base_after_extension;
}

/// True when M's stated constants match its field list.
template <class M>
constexpr bool LayoutMatches() {
  return ComputeCrcExtra<M>() == M::kCrcExtra && ComputeMinLength<M>() == M::kMinLength &&
         ComputeMaxLength<M>() == M::kMaxLength && FieldsInWireOrder<M>() && M::kMaxLength <= 255 &&
         M::kId < (1U << 24);
}

/// Writes m's full (untruncated) payload, M::kMaxLength bytes, to `out`.
template <class M>
constexpr void PackPayload(const M& m, std::span<std::uint8_t, M::kMaxLength> out) {
  internal::PackVisitor v{out.data()};
  M::VisitFields(m, v);
}

/// Reads a message from `payload`, which may be shorter than M::kMaxLength (a MAVLink 2
/// payload truncated of its trailing zero bytes, or one without extensions): the missing
/// bytes read as zero. Bytes beyond M::kMaxLength are ignored.
template <class M>
constexpr M UnpackPayload(std::span<const std::uint8_t> payload) {
  std::array<std::uint8_t, M::kMaxLength> full{};
  const std::size_t n = payload.size() < full.size() ? payload.size() : full.size();
  for (std::size_t i = 0; i < n; ++i) full[i] = payload[i];
  M m{};
  internal::UnpackVisitor v{full.data()};
  M::VisitFields(m, v);
  return m;
}

}  // namespace fnmpc::mavlink

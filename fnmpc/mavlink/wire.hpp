// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <type_traits>

/// Little-endian wire encoding of MAVLink field types (mavlink.io/en/guide/serialization.html:
/// every field is little-endian; float and double are IEEE 754 binary32 and binary64).
/// Independent of the host's byte order. The caller guarantees room: these helpers are the
/// innermost loop of packing and check nothing.
namespace fnmpc::mavlink::wire {

/// Field types of MAVLink messages: the integers of <cstdint>, float, double, and char
/// (MAVLink's char arrays; none of the supported messages has one).
template <class T>
inline constexpr bool kIsFieldType =
    std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::int8_t> ||
    std::is_same_v<T, std::uint16_t> || std::is_same_v<T, std::int16_t> ||
    std::is_same_v<T, std::uint32_t> || std::is_same_v<T, std::int32_t> ||
    std::is_same_v<T, std::uint64_t> || std::is_same_v<T, std::int64_t> ||
    std::is_same_v<T, float> || std::is_same_v<T, double> || std::is_same_v<T, char>;

/// The unsigned integer of T's size (the bit pattern on the wire).
template <class T>
using Bits = std::conditional_t<
    sizeof(T) == 1, std::uint8_t,
    std::conditional_t<sizeof(T) == 2, std::uint16_t,
                       std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>>;

/// Writes `value` at `out` (sizeof(T) bytes, least significant first); returns the byte after.
template <class T>
constexpr std::uint8_t* Put(std::uint8_t* out, T value) {
  static_assert(kIsFieldType<T>);
  const auto bits = std::bit_cast<Bits<T>>(value);
  for (std::size_t i = 0; i < sizeof(T); ++i) out[i] = static_cast<std::uint8_t>(bits >> (8 * i));
  return out + sizeof(T);
}

/// Reads a T from `in` (sizeof(T) bytes, least significant first) into *value; returns the
/// byte after.
template <class T>
constexpr const std::uint8_t* Get(const std::uint8_t* in, T* value) {
  static_assert(kIsFieldType<T>);
  Bits<T> bits = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i)
    bits |= static_cast<Bits<T>>(Bits<T>{in[i]} << (8 * i));
  *value = std::bit_cast<T>(bits);
  return in + sizeof(T);
}

/// Arrays are their elements one after the other.
template <class T, std::size_t N>
constexpr std::uint8_t* Put(std::uint8_t* out, const std::array<T, N>& values) {
  for (const T& v : values) out = Put(out, v);
  return out;
}
template <class T, std::size_t N>
constexpr const std::uint8_t* Get(const std::uint8_t* in, std::array<T, N>* values) {
  for (T& v : *values) in = Get(in, &v);
  return in;
}

/// 24-bit and 48-bit little-endian integers (the v2 message id, the signature timestamp).
constexpr std::uint8_t* PutUint(std::uint8_t* out, std::uint64_t value, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; ++i) out[i] = static_cast<std::uint8_t>(value >> (8 * i));
  return out + bytes;
}
constexpr std::uint64_t GetUint(const std::uint8_t* in, std::size_t bytes) {
  std::uint64_t value = 0;
  for (std::size_t i = 0; i < bytes; ++i) value |= std::uint64_t{in[i]} << (8 * i);
  return value;
}

}  // namespace fnmpc::mavlink::wire

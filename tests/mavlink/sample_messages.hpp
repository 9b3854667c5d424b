// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "fnmpc/mavlink/encoder.hpp"
#include "fnmpc/mavlink/message.hpp"
#include "fnmpc/mavlink/message_layout.hpp"

/// Deterministic messages with non-trivial field values for the mavlink tests: every field
/// drawn from a seeded std::mt19937, with the types' extremes and zeros mixed in (zeros at
/// the end of a payload exercise truncation). Floats are finite.
namespace fnmpc::mavlink::testing {

/// Lower-case hex of bytes ("0a1b..."), for digests, keys and frames in test messages.
inline std::string Hex(std::span<const std::uint8_t> bytes) {
  std::string s;
  char b[3];
  for (const std::uint8_t x : bytes) {
    std::snprintf(b, sizeof(b), "%02x", x);
    s += b;
  }
  return s;
}

class RandomFiller {
 public:
  /// zero_probability: chance that a field is 0 (whole trailing extensions then vanish).
  RandomFiller(std::mt19937* rng, double zero_probability)
      : rng_(rng), zero_probability_(zero_probability) {}

  template <class T>
  void Field(std::string_view /*name*/, T& value) {
    Fill(&value);
  }
  template <class T>
  void Extension(std::string_view /*name*/, T& value) {
    Fill(&value);
  }

 private:
  template <class T, std::size_t N>
  void Fill(std::array<T, N>* values) {
    for (T& v : *values) Fill(&v);
  }
  template <class T>
  void Fill(T* value) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const double pick = u(*rng_);
    if (pick < zero_probability_) {
      *value = T{};
    } else if constexpr (std::is_floating_point_v<T>) {
      std::uniform_real_distribution<T> d(-1000.0, 1000.0);
      *value = pick < zero_probability_ + 0.05 ? std::numeric_limits<T>::max() : d(*rng_);
    } else if (pick < zero_probability_ + 0.05) {
      *value = std::numeric_limits<T>::max();
    } else if (pick < zero_probability_ + 0.1) {
      *value = std::numeric_limits<T>::min();
    } else {
      using Wide = std::conditional_t<std::is_signed_v<T>, std::int64_t, std::uint64_t>;
      std::uniform_int_distribution<Wide> d(std::numeric_limits<T>::min(),
                                            std::numeric_limits<T>::max());
      *value = static_cast<T>(d(*rng_));
    }
  }

  std::mt19937* rng_;
  double zero_probability_;
};

/// A message of alternative `index` of Message with random fields.
inline Message RandomMessage(std::size_t index, std::mt19937* rng, double zero_probability = 0.1) {
  Message message;
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    ((index == I ? void(message.template emplace<I>()) : void()), ...);
  }
  (std::make_index_sequence<kNumMessages>());
  RandomFiller filler(rng, zero_probability);
  std::visit([&](auto& m) { std::decay_t<decltype(m)>::VisitFields(m, filler); }, message);
  return message;
}

/// A message of a random alternative with random fields.
inline Message RandomMessage(std::mt19937* rng, double zero_probability = 0.1) {
  std::uniform_int_distribution<std::size_t> pick(0, kNumMessages - 1);
  return RandomMessage(pick(*rng), rng, zero_probability);
}

/// True when the messages hold the same alternative with bit-identical payloads (so that
/// NaN fields compare equal too).
inline bool SamePayload(const Message& a, const Message& b) {
  if (a.index() != b.index()) return false;
  std::array<std::uint8_t, kMaxPayloadLength> pa{}, pb{};
  const std::size_t na = PackPayload(a, pa);
  const std::size_t nb = PackPayload(b, pb);
  return na == nb && pa == pb;
}

/// The frame `encoder` writes for `message`, as a vector.
inline std::vector<std::uint8_t> EncodeToVector(Encoder* encoder, const Message& message) {
  std::array<std::uint8_t, kMaxFrameLength> buffer{};
  const std::size_t n = encoder->Encode(message, buffer);
  return {buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(n)};
}

/// A test key: bytes 1, 2, ..., 32 plus `salt`.
inline SigningKey TestKey(std::uint8_t salt = 0) {
  SigningKey key{};
  for (std::size_t i = 0; i < key.size(); ++i) key[i] = static_cast<std::uint8_t>(i + 1 + salt);
  return key;
}

}  // namespace fnmpc::mavlink::testing

// SPDX-License-Identifier: BSD-3-Clause
// The codec allocates nothing: encoding, signing, parsing, decoding and signature checks run
// on fixed buffers (tests/support/malloc_counter.hpp counts every C allocation call).
#include <gtest/gtest.h>

#include <array>
#include <random>
#include <vector>

#include "fnmpc/mavlink/encoder.hpp"
#include "fnmpc/mavlink/parser.hpp"
#include "tests/mavlink/sample_messages.hpp"
#include "tests/support/malloc_counter.hpp"

namespace fnmpc::mavlink {
namespace {

TEST(MavlinkAllocationTest, EncodeAndParseAllocateNothing) {
  // Given messages, an encoder and a parser with a key, built beforehand
  std::mt19937 rng(1);
  std::vector<Message> messages;
  for (int i = 0; i < 100; ++i) messages.push_back(testing::RandomMessage(&rng));
  Encoder encoder(1, 1);
  encoder.EnableSigning(testing::TestKey(), 0);
  Parser parser;
  parser.SetSigningKey(testing::TestKey());
  std::array<std::uint8_t, kMaxFrameLength> buffer{};
  std::size_t decoded = 0;
  // When every message is encoded and parsed, with a garbage byte and a false start between
  const long mallocs = fnmpc::testing::CountMallocs([&] {
    for (const Message& m : messages) {
      const std::size_t n = encoder.Encode(m, buffer);
      parser.Parse(std::uint8_t{0x42}, [&](const Frame&) {});
      parser.Parse(kStartByte, [&](const Frame&) {});
      parser.Parse(std::span<const std::uint8_t>(buffer.data(), n),
                   [&](const Frame& f) { decoded += f.message.index() == m.index() ? 1 : 0; });
    }
  });
  // Then nothing was allocated and every frame came through
  EXPECT_EQ(mallocs, 0);
  EXPECT_EQ(decoded, messages.size());
}

}  // namespace
}  // namespace fnmpc::mavlink

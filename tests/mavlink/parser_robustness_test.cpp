// SPDX-License-Identifier: BSD-3-Clause
// The parser against hostile streams: many deterministic random streams of valid frames
// mixed with garbage, corrupted, truncated, wrong-checksum, unknown-id, over-long and (with
// signing) unsigned, wrongly signed and replayed frames, and a flood of false headers ten
// times the volume of the valid frames. Every valid frame must come out, in order, byte for
// byte; the counters must account for every byte and every rejected frame. The suite runs
// under ASan and UBSan (scripts/test.sh), which also checks the parser's buffer handling.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "fnmpc/mavlink/encoder.hpp"
#include "fnmpc/mavlink/parser.hpp"
#include "tests/mavlink/sample_messages.hpp"

namespace fnmpc::mavlink {
namespace {

using testing::EncodeToVector;
using testing::RandomMessage;
using testing::TestKey;
using Bytes = std::vector<std::uint8_t>;

struct Expected {
  std::vector<Bytes> valid;   // frames that must come out, in order
  std::size_t wrong_crc = 0;  // candidates that must fail their checksum (at least)
  std::size_t unknown = 0;
  std::size_t bad_length = 0;
  std::size_t unsigned_frames = 0;
  std::size_t bad_signature = 0;  // wrongly signed, or cut in the signature
  std::size_t replayed = 0;
};

struct Options {
  bool clean = false;    // no 0xFD but the start bytes of injected frames: exact counters
  bool signing = false;  // the parser has a key; valid frames are signed
};

bool HasInnerStartByte(const Bytes& f) {
  return std::find(f.begin() + 1, f.end(), kStartByte) != f.end();
}

class StreamMaker {
 public:
  StreamMaker(std::uint32_t seed, Options options)
      : rng_(seed),
        options_(options),
        sender_(1, 1),
        other_(2, 1),
        unsigned_(3, 1),
        stranger_(4, 1) {
    if (options_.signing) {
      sender_.EnableSigning(TestKey(), 0);
      other_.EnableSigning(TestKey(), 1);
      stranger_.EnableSigning(TestKey(9), 0);
    }
  }

  void Make(int segments, Bytes* stream, Expected* expected) {
    for (int i = 0; i < segments; ++i) {
      switch (rng_() % (options_.signing ? 10 : 7)) {
        case 0:
        case 1:
          Valid(stream, expected);
          break;
        case 2:
          Garbage(stream);
          break;
        case 3:
          Corrupted(stream, expected);
          break;
        case 4:
          Truncated(stream, expected);
          break;
        case 5:
          UnknownId(stream, expected);
          break;
        case 6:
          BadLength(stream, expected);
          break;
        case 7:
          Append(stream, Frame(&unsigned_));
          ++expected->unsigned_frames;
          break;
        case 8:
          Append(stream, Frame(&stranger_));
          ++expected->bad_signature;
          break;
        case 9:
          if (!expected->valid.empty()) {
            Append(stream, expected->valid[rng_() % expected->valid.size()]);
            ++expected->replayed;
          }
          break;
      }
      // Valid frames come often, so that each kind of damage sits before one.
      if (rng_() % 2 == 0) Valid(stream, expected);
    }
    Valid(stream, expected);
    Bytes tail(kMaxFrameLength + 20);  // completes any pending false candidate
    for (auto& b : tail) b = NonStart();
    Append(stream, tail);
  }

 private:
  std::uint8_t NonStart() {
    const auto b = static_cast<std::uint8_t>(rng_());
    return b == kStartByte ? 0x00 : b;
  }
  static void Append(Bytes* stream, const Bytes& b) {
    stream->insert(stream->end(), b.begin(), b.end());
  }

  // A frame of `encoder`, free of inner start bytes when the stream must be clean.
  Bytes Frame(Encoder* encoder) {
    for (;;) {
      Bytes f = EncodeToVector(encoder, RandomMessage(&rng_));
      if (!options_.clean || !HasInnerStartByte(f)) return f;
    }
  }

  void Valid(Bytes* stream, Expected* expected) {
    Encoder* e = rng_() % 4 == 0 ? &other_ : &sender_;
    const Bytes f = Frame(e);
    Append(stream, f);
    expected->valid.push_back(f);
  }

  void Garbage(Bytes* stream) {
    Bytes g(rng_() % 60);
    for (auto& b : g) {
      b = !options_.clean && rng_() % 8 == 0 ? kStartByte : NonStart();
    }
    Append(stream, g);
  }

  void Corrupted(Bytes* stream, Expected* expected) {
    Bytes f = Frame(&sender_);
    const std::size_t crc_end = kHeaderLength + f[1] + kChecksumLength;
    // Clean: damage the payload or checksum (a checksum failure for sure); else any byte.
    const std::size_t at =
        options_.clean ? kHeaderLength + rng_() % (crc_end - kHeaderLength) : rng_() % f.size();
    std::uint8_t flipped;
    do {
      flipped = static_cast<std::uint8_t>(f[at] ^ (1 + rng_() % 255));
    } while (options_.clean && flipped == kStartByte);
    if (options_.clean) ++expected->wrong_crc;
    f[at] = flipped;
    Append(stream, f);
  }

  void Truncated(Bytes* stream, Expected* expected) {
    const Bytes f = Frame(&sender_);
    // Clean: cut after the header (the candidate then fails its checksum); else anywhere.
    const std::size_t cut = options_.clean ? kHeaderLength + rng_() % (f.size() - kHeaderLength)
                                           : 1 + rng_() % (f.size() - 1);
    if (options_.clean) {
      // Cut in the signature: the checksum holds and the signature fails.
      const std::size_t crc_end = kHeaderLength + f[1] + kChecksumLength;
      ++(cut < crc_end ? expected->wrong_crc : expected->bad_signature);
    }
    Append(stream, Bytes(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(cut)));
    // A byte that differs from the first one cut off: otherwise what follows (a frame's
    // start byte, garbage) could complete the frame again, which would then be valid.
    std::uint8_t separator;
    do {
      separator = NonStart();
    } while (separator == f[cut]);
    stream->push_back(separator);
  }

  void UnknownId(Bytes* stream, Expected* expected) {
    for (;;) {
      Bytes payload(1 + rng_() % 60);
      for (auto& b : payload) b = NonStart();
      FrameSpec spec;
      spec.message_id = 24 + rng_() % 6;  // GPS_RAW_INT .. : not supported
      spec.crc_extra = static_cast<std::uint8_t>(rng_());
      spec.sequence = static_cast<std::uint8_t>(rng_());
      Bytes f(kMaxFrameLength);
      f.resize(WriteFrame(spec, payload, f));
      if (options_.clean && HasInnerStartByte(f)) continue;
      Append(stream, f);
      ++expected->unknown;
      return;
    }
  }

  void BadLength(Bytes* stream, Expected* expected) {
    for (;;) {
      // A HEARTBEAT (max 9 bytes) or COMMAND_ACK (max 10) with a longer payload
      const bool hb = rng_() % 2 == 0;
      Bytes payload((hb ? 10 : 11) + rng_() % 20);
      for (auto& b : payload) b = NonStart();
      FrameSpec spec;
      spec.message_id = hb ? Heartbeat::kId : CommandAck::kId;
      spec.crc_extra = hb ? Heartbeat::kCrcExtra : CommandAck::kCrcExtra;
      Bytes f(kMaxFrameLength);
      f.resize(WriteFrame(spec, payload, f));
      if (options_.clean && HasInnerStartByte(f)) continue;
      Append(stream, f);
      ++expected->bad_length;
      return;
    }
  }

  std::mt19937 rng_;
  Options options_;
  Encoder sender_;    // valid frames (signed when signing)
  Encoder other_;     // valid frames of a second stream
  Encoder unsigned_;  // never signs
  Encoder stranger_;  // signs with another key
};

struct Result {
  std::vector<Bytes> frames;
  ParserCounters counters;
  std::size_t buffered = 0;
};

Result ParseInChunks(const Bytes& stream, bool signing, std::mt19937* rng) {
  Parser parser;
  if (signing) parser.SetSigningKey(TestKey());
  Result r;
  // Random chunk sizes: the result must not depend on how the bytes arrive.
  for (std::size_t at = 0; at < stream.size();) {
    const std::size_t n = std::min<std::size_t>(1 + (*rng)() % 64, stream.size() - at);
    parser.Parse(std::span(stream).subspan(at, n),
                 [&](const Frame& f) { r.frames.emplace_back(f.bytes.begin(), f.bytes.end()); });
    at += n;
  }
  r.counters = parser.counters();
  r.buffered = parser.buffered();
  return r;
}

std::size_t TotalSize(const std::vector<Bytes>& frames) {
  std::size_t n = 0;
  for (const Bytes& f : frames) n += f.size();
  return n;
}

class ParserRobustnessTest : public ::testing::TestWithParam<Options> {};

TEST_P(ParserRobustnessTest, EveryValidFrameSurvivesDamagedStreams) {
  const Options options = GetParam();
  const int streams = options.clean ? 150 : 400;
  for (int s = 0; s < streams; ++s) {
    // Given a random stream of valid and damaged frames and garbage
    const auto seed = static_cast<std::uint32_t>(1000 * (options.clean + 2 * options.signing) + s);
    StreamMaker maker(seed, options);
    Bytes stream;
    Expected expected;
    maker.Make(60, &stream, &expected);
    // When it is parsed
    std::mt19937 chunks(seed);
    const Result r = ParseInChunks(stream, options.signing, &chunks);
    // Then exactly the valid frames come out, in order, byte for byte
    if (r.frames.size() != expected.valid.size()) {
      for (std::size_t i = 0; i < r.frames.size(); ++i) {
        if (i >= expected.valid.size() || r.frames[i] != expected.valid[i]) {
          std::string h;
          for (auto x : r.frames[i]) h += std::to_string(x) + " ";
          std::string e;
          if (i < expected.valid.size())
            for (auto x : expected.valid[i]) e += std::to_string(x) + " ";
          ADD_FAILURE() << "frame " << i << " got " << h << "\n expected " << e;
          break;
        }
      }
    }
    ASSERT_EQ(r.frames.size(), expected.valid.size()) << "seed " << seed;
    for (std::size_t i = 0; i < r.frames.size(); ++i) {
      ASSERT_EQ(r.frames[i], expected.valid[i]) << "seed " << seed << " frame " << i;
    }
    // And the counters account for every byte and every injected fault
    const ParserCounters& c = r.counters;
    EXPECT_EQ(c.bytes_received, stream.size());
    EXPECT_EQ(c.frames_ok, expected.valid.size());
    EXPECT_EQ(c.bytes_in_frames, TotalSize(expected.valid));
    EXPECT_EQ(c.bytes_discarded + c.bytes_in_unknown_frames,
              stream.size() - TotalSize(expected.valid));
    EXPECT_EQ(r.buffered, 0U);
    EXPECT_EQ(c.signature_failures, c.unsigned_rejected + c.bad_signatures + c.timestamps_rejected);
    if (options.clean) {
      // Each injected frame is one candidate failing for its one reason.
      EXPECT_EQ(c.crc_errors, expected.wrong_crc) << "seed " << seed;
      EXPECT_EQ(c.unknown_ids, expected.unknown) << "seed " << seed;
      EXPECT_EQ(c.bad_lengths, expected.bad_length) << "seed " << seed;
      EXPECT_EQ(c.bad_incompat_flags, 0U);
      EXPECT_EQ(c.unsigned_rejected, expected.unsigned_frames) << "seed " << seed;
      EXPECT_EQ(c.bad_signatures, expected.bad_signature) << "seed " << seed;
      EXPECT_EQ(c.timestamps_rejected, expected.replayed) << "seed " << seed;
    } else {
      // False starts in garbage and in damaged frames add failures of any kind.
      EXPECT_GE(c.unknown_ids, expected.unknown);
      EXPECT_GE(c.bad_lengths, expected.bad_length);
      EXPECT_GE(c.unsigned_rejected, expected.unsigned_frames);
      EXPECT_GE(c.bad_signatures, expected.bad_signature);
      EXPECT_GE(c.timestamps_rejected, expected.replayed);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Streams, ParserRobustnessTest,
                         ::testing::Values(Options{false, false}, Options{true, false},
                                           Options{false, true}, Options{true, true}),
                         [](const auto& info) {
                           return std::string(info.param.clean ? "Clean" : "Random") +
                                  (info.param.signing ? "Signed" : "Unsigned");
                         });

TEST(ParserFloodTest, TenfoldFloodOfFalseHeaders) {
  // Given valid frames buried in ten times their volume of false headers: each claims a
  // supported id with its longest payload, so that every one of them holds the parser until
  // it is complete and fails its checksum, with the valid frames inside it
  std::mt19937 rng(77);
  Encoder sender(1, 1);
  std::vector<Bytes> valid;
  Bytes stream;
  std::size_t false_headers = 0;
  for (int i = 0; i < 300; ++i) {
    Bytes f;
    do {
      f = EncodeToVector(&sender, RandomMessage(&rng));
    } while (HasInnerStartByte(f));
    std::size_t flood = 0;
    while (flood < 10 * f.size()) {
      const MessageInfo& info = SupportedMessages()[rng() % kNumMessages];
      Bytes h{kStartByte,
              static_cast<std::uint8_t>(info.max_length),
              0,
              0,
              static_cast<std::uint8_t>(rng()),
              1,
              1,
              static_cast<std::uint8_t>(info.id),
              static_cast<std::uint8_t>(info.id >> 8),
              static_cast<std::uint8_t>(info.id >> 16)};
      for (std::size_t k = rng() % 8; k > 0; --k)
        h.push_back(static_cast<std::uint8_t>(rng() % 0xFD));
      stream.insert(stream.end(), h.begin(), h.end());
      flood += h.size();
      ++false_headers;
    }
    stream.insert(stream.end(), f.begin(), f.end());
    valid.push_back(f);
  }
  stream.insert(stream.end(), kMaxFrameLength, 0x00);
  // When it is parsed
  Parser parser;
  std::vector<Bytes> got;
  parser.Parse(stream, [&](const Frame& f) { got.emplace_back(f.bytes.begin(), f.bytes.end()); });
  // Then every valid frame comes out and every false header is one checksum failure
  ASSERT_EQ(got.size(), valid.size());
  for (std::size_t i = 0; i < got.size(); ++i) ASSERT_EQ(got[i], valid[i]) << i;
  EXPECT_EQ(parser.counters().crc_errors, false_headers);
  EXPECT_EQ(parser.counters().bytes_discarded, stream.size() - TotalSize(valid));
  EXPECT_GE(stream.size(), 10 * TotalSize(valid));
}

}  // namespace
}  // namespace fnmpc::mavlink

// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target for the MAVLink parser (docs/mavlink.md, "Fuzzing"). Built only by clang
// with -fsanitize=fuzzer (tests/mavlink/CMakeLists.txt); run it under ASan and UBSan:
//   build-fuzz/tests/mavlink/mavlink_parser_fuzz -max_total_time=300 corpus/
// The first input byte selects the setting (bit 0: a signing key is set; bit 1: repair, see
// Repair(); bits 2-7: the chunk size the second parser is fed with); the rest is the stream.
// Random bytes almost never hold a valid checksum, so in repair mode the harness first
// writes the right checksum (and signature) into every place of the stream that looks like
// a frame of a supported message: the fuzzer then reaches decoding, signing and the
// interplay of valid frames with damaged ones. Checked properties:
//   - every received byte ends in a frame, is discarded, or is buffered;
//   - the frames do not depend on how the stream is chunked;
//   - each frame is well formed: start byte, length = header + payload + checksum
//     (+ signature), its header fields match its bytes;
//   - each frame parses again, alone, to the same frame, and its message re-encodes to a
//     frame that decodes to the same payload.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "fnmpc/mavlink/crc.hpp"
#include "fnmpc/mavlink/encoder.hpp"
#include "fnmpc/mavlink/parser.hpp"
#include "fnmpc/mavlink/wire.hpp"

namespace {

using fnmpc::mavlink::Frame;
using fnmpc::mavlink::Parser;
namespace mav = fnmpc::mavlink;

void Check(bool condition) {
  if (!condition) __builtin_trap();
}

struct Copy {
  std::vector<std::uint8_t> bytes;
  mav::FrameHeader header;
  std::array<std::uint8_t, mav::kMaxPayloadLength> payload{};
  std::size_t payload_size = 0;
};

Copy CopyOf(const Frame& f) {
  Copy c;
  c.bytes.assign(f.bytes.begin(), f.bytes.end());
  c.header = f.header;
  c.payload_size = mav::PackPayload(f.message, c.payload);
  return c;
}

void CheckConservation(const Parser& p) {
  const mav::ParserCounters& c = p.counters();
  Check(c.bytes_received ==
        c.bytes_in_frames + c.bytes_in_unknown_frames + c.bytes_discarded + p.buffered());
  Check(c.signature_failures == c.unsigned_rejected + c.bad_signatures + c.timestamps_rejected);
}

mav::SigningKey Key() {
  mav::SigningKey key{};
  for (std::size_t i = 0; i < key.size(); ++i) key[i] = static_cast<std::uint8_t>(3 * i + 1);
  return key;
}

// Gives every candidate header (start byte, supported id, length within bounds, whole frame
// in the stream) its correct checksum and, if flagged signed, its signature under Key(),
// left to right (a repair may change bytes of an overlapping candidate: the stream is just
// some other stream then).
void Repair(std::vector<std::uint8_t>* s) {
  const mav::SigningKey key = Key();
  for (std::size_t i = 0; i + mav::kHeaderLength <= s->size(); ++i) {
    std::uint8_t* f = s->data() + i;
    if (f[0] != mav::kStartByte) continue;
    const auto id = static_cast<std::uint32_t>(mav::wire::GetUint(f + 7, 3));
    const mav::MessageInfo* info = mav::FindMessageInfo(id);
    if (info == nullptr || f[1] > info->max_length) continue;
    const bool is_signed = (f[2] & mav::kIncompatFlagSigned) != 0;
    const std::size_t crc_at = mav::kHeaderLength + f[1];
    const std::size_t length =
        crc_at + mav::kChecksumLength + (is_signed ? mav::kSignatureLength : 0);
    if (i + length > s->size()) continue;
    std::uint16_t crc = mav::CrcAccumulate(std::span<const std::uint8_t>(f + 1, crc_at - 1));
    crc = mav::CrcAccumulate(info->crc_extra, crc);
    mav::wire::Put(f + crc_at, crc);
    if (is_signed) {
      const std::size_t sig_at = crc_at + mav::kChecksumLength;
      const auto sig = mav::ComputeSignature(key, std::span<const std::uint8_t>(f, sig_at),
                                             f[sig_at], mav::wire::GetUint(f + sig_at + 1, 6));
      std::memcpy(f + sig_at + 7, sig.data(), sig.size());
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const bool signing = (data[0] & 1) != 0;
  const std::size_t chunk = 1 + (data[0] >> 2);
  std::vector<std::uint8_t> bytes(data + 1, data + size);
  if ((data[0] & 2) != 0) Repair(&bytes);
  const std::span<const std::uint8_t> stream(bytes);

  Parser whole;
  Parser chunked;
  if (signing) {
    whole.SetSigningKey(Key());
    chunked.SetSigningKey(Key());
  }
  std::vector<Copy> a;
  std::vector<Copy> b;
  whole.Parse(stream, [&](const Frame& f) { a.push_back(CopyOf(f)); });
  for (std::size_t at = 0; at < stream.size(); at += chunk) {
    const std::size_t n = std::min(chunk, stream.size() - at);
    chunked.Parse(stream.subspan(at, n), [&](const Frame& f) { b.push_back(CopyOf(f)); });
  }
  CheckConservation(whole);
  CheckConservation(chunked);
  Check(whole.counters().bytes_received == stream.size());
  Check(a.size() == b.size() && a.size() == whole.counters().frames_ok);

  for (std::size_t i = 0; i < a.size(); ++i) {
    const Copy& f = a[i];
    Check(f.bytes == b[i].bytes);
    Check(f.bytes.size() >= mav::kHeaderLength + mav::kChecksumLength);
    Check(f.bytes[0] == mav::kStartByte);
    Check(f.header.payload_length == f.bytes[1]);
    Check(f.header.incompat_flags == f.bytes[2]);
    Check(f.header.sequence == f.bytes[4]);
    const bool is_signed = (f.header.incompat_flags & mav::kIncompatFlagSigned) != 0;
    Check(!signing || is_signed);
    Check(f.bytes.size() == mav::kHeaderLength + f.header.payload_length + mav::kChecksumLength +
                                (is_signed ? mav::kSignatureLength : 0));
    const mav::MessageInfo* info = mav::FindMessageInfo(f.header.message_id);
    Check(info != nullptr && f.header.payload_length <= info->max_length);

    // The frame alone parses to the same frame (without a key: a fresh parser has no stream
    // history to reject its timestamp against).
    Parser again;
    std::size_t count = 0;
    again.Parse(std::span<const std::uint8_t>(f.bytes), [&](const Frame& g) {
      ++count;
      Check(std::equal(g.bytes.begin(), g.bytes.end(), f.bytes.begin(), f.bytes.end()));
    });
    Check(count == 1);

    // Its message re-encodes to a frame that decodes to the same payload.
    mav::FrameSpec spec;
    spec.message_id = info->id;
    spec.crc_extra = info->crc_extra;
    const std::size_t length = mav::TruncatedPayloadLength(
        std::span<const std::uint8_t>(f.payload.data(), f.payload_size));
    std::array<std::uint8_t, mav::kMaxFrameLength> out{};
    const std::size_t n =
        mav::WriteFrame(spec, std::span<const std::uint8_t>(f.payload.data(), length), out);
    Check(n > 0);
    count = 0;
    again.Parse(std::span<const std::uint8_t>(out.data(), n), [&](const Frame& g) {
      ++count;
      std::array<std::uint8_t, mav::kMaxPayloadLength> p{};
      const std::size_t m = mav::PackPayload(g.message, p);
      Check(m == f.payload_size && std::memcmp(p.data(), f.payload.data(), m) == 0);
    });
    Check(count == 1);
  }
  return 0;
}

// SPDX-License-Identifier: BSD-3-Clause
// A ULog writer for the tests (after the message layouts of PX4's ULog specification): builds
// synthetic logs byte by byte, including broken ones.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace fnmpc::ulog::testing {

using Bytes = std::vector<std::uint8_t>;

template <class T>
void Put(Bytes& b, T v) {
  const std::size_t n = b.size();
  b.resize(n + sizeof(T));
  std::memcpy(b.data() + n, &v, sizeof(T));
}
/// Appends n bytes (resize and memcpy: GCC 12 at -O3 warns falsely about vector::insert here).
inline void Append(Bytes& b, const void* data, std::size_t n) {
  if (n == 0) return;
  const std::size_t at = b.size();
  b.resize(at + n);
  std::memcpy(b.data() + at, data, n);
}
inline void PutText(Bytes& b, const std::string& s) { Append(b, s.data(), s.size()); }

class Builder {
 public:
  explicit Builder(std::uint8_t version = 1) {
    bytes_ = {0x55, 0x4c, 0x6f, 0x67, 0x01, 0x12, 0x35, version};
    Put<std::uint64_t>(bytes_, 1000);
  }
  void Message(char type, const Bytes& payload) {
    Put<std::uint16_t>(bytes_, static_cast<std::uint16_t>(payload.size()));
    bytes_.push_back(static_cast<std::uint8_t>(type));
    Append(bytes_, payload.data(), payload.size());
  }
  void FlagBits(std::uint8_t incompat0, std::array<std::uint64_t, 3> appended = {}) {
    Bytes p(16, 0);
    p[8] = incompat0;
    for (std::uint64_t a : appended) Put(p, a);
    Message('B', p);
  }
  void Format(const std::string& text) {
    Bytes p;
    PutText(p, text);
    Message('F', p);
  }
  void Info(const std::string& key, const Bytes& value, char type = 'I', bool continued = false) {
    Bytes p;
    if (type == 'M') p.push_back(continued ? 1 : 0);
    p.push_back(static_cast<std::uint8_t>(key.size()));
    PutText(p, key);
    Append(p, value.data(), value.size());
    Message(type, p);
  }
  void Param(const std::string& key, const Bytes& value, char type, std::uint8_t default_types) {
    Bytes p;
    if (type == 'Q') p.push_back(default_types);
    p.push_back(static_cast<std::uint8_t>(key.size()));
    PutText(p, key);
    Append(p, value.data(), value.size());
    Message(type, p);
  }
  void ParamInt(const std::string& name, std::int32_t v, char type = 'P', std::uint8_t dt = 0) {
    Bytes value;
    Put(value, v);
    Param("int32_t " + name, value, type, dt);
  }
  void ParamFloat(const std::string& name, float v, char type = 'P', std::uint8_t dt = 0) {
    Bytes value;
    Put(value, v);
    Param("float " + name, value, type, dt);
  }
  void Add(std::uint8_t multi_id, std::uint16_t msg_id, const std::string& name) {
    Bytes p{multi_id};
    Put(p, msg_id);
    PutText(p, name);
    Message('A', p);
  }
  void Data(std::uint16_t msg_id, const Bytes& record) {
    Bytes p;
    Put(p, msg_id);
    Append(p, record.data(), record.size());
    Message('D', p);
  }
  void Log(char level, std::uint64_t ts, const std::string& text) {
    Bytes p{static_cast<std::uint8_t>(level)};
    Put(p, ts);
    PutText(p, text);
    Message('L', p);
  }
  void Tagged(char level, std::uint16_t tag, std::uint64_t ts, const std::string& text) {
    Bytes p{static_cast<std::uint8_t>(level)};
    Put(p, tag);
    Put(p, ts);
    PutText(p, text);
    Message('C', p);
  }
  void Sync() { Message('S', {0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12}); }
  void Dropout(std::uint16_t ms) {
    Bytes p;
    Put(p, ms);
    Message('O', p);
  }
  [[nodiscard]] std::size_t size() const { return bytes_.size(); }
  Bytes& bytes() { return bytes_; }

 private:
  Bytes bytes_;
};

}  // namespace fnmpc::ulog::testing

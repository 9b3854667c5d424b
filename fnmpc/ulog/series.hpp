// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "fnmpc/ulog/reader.hpp"

namespace fnmpc::ulog {

/// The numeric columns of one topic instance, as doubles, with its timestamps [us].
struct TopicSeries {
  std::string topic;
  std::uint8_t multi_id = 0;
  std::vector<std::uint64_t> timestamp;  ///< [us], as logged
  std::vector<std::string> names;        ///< flattened column names ("q[0]", "esc[1].esc_rpm")
  std::vector<std::vector<double>> columns;

  [[nodiscard]] std::size_t size() const { return timestamp.size(); }
  [[nodiscard]] bool Has(std::string_view name) const;
  /// Column `name`; throws std::runtime_error naming the topic, the instance and the fields
  /// it has when there is no such column.
  [[nodiscard]] const std::vector<double>& Column(std::string_view name) const;
};

/// Series of several topics, every instance of each.
class LogSeries {
 public:
  /// Reads the data section of `reader` once (Reader::ReadData) and keeps the numeric columns
  /// of every instance of the topics named in `topics` (strings are left out).
  static LogSeries Read(Reader& reader, const std::vector<std::string>& topics);

  /// Instance `multi_id` of `topic`, or nullptr when the log has none (or no data for it).
  [[nodiscard]] const TopicSeries* Find(std::string_view topic, std::uint8_t multi_id = 0) const;
  /// Like Find, but throws std::runtime_error "FILE: no data of topic 'x' (instance i)".
  [[nodiscard]] const TopicSeries& Get(std::string_view topic, std::uint8_t multi_id = 0) const;
  [[nodiscard]] const std::vector<TopicSeries>& all() const { return series_; }

 private:
  std::string file_;
  std::vector<TopicSeries> series_;
};

}  // namespace fnmpc::ulog

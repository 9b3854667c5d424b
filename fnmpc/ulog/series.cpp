// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/ulog/series.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace fnmpc::ulog {

bool TopicSeries::Has(std::string_view name) const {
  return std::find(names.begin(), names.end(), name) != names.end();
}

const std::vector<double>& TopicSeries::Column(std::string_view name) const {
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) {
    std::string have;
    for (const std::string& n : names) have += (have.empty() ? "" : ", ") + n;
    throw std::runtime_error("topic '" + topic + "' (instance " + std::to_string(multi_id) +
                             ") has no field '" + std::string(name) + "' (it has: " + have + ")");
  }
  return columns[static_cast<std::size_t>(it - names.begin())];
}

LogSeries LogSeries::Read(Reader& reader, const std::vector<std::string>& topics) {
  LogSeries out;
  out.file_ = reader.path();
  // Subscription index -> series index (-1: not wanted); numeric columns of each.
  std::vector<int> series_of;
  std::vector<std::vector<const ulog::Column*>> wanted;
  reader.ReadData([&](const DataMessage& m) {
    const Subscription& sub = *m.subscription;
    const auto index = static_cast<std::size_t>(&sub - reader.subscriptions().data());
    while (series_of.size() <= index) {
      const Subscription& s = reader.subscriptions()[series_of.size()];
      const bool want = std::find(topics.begin(), topics.end(), s.name) != topics.end();
      int found = -1;
      if (want) {
        // A topic instance subscribed twice (after an unsubscription) continues its series.
        for (std::size_t k = 0; k < out.series_.size(); ++k) {
          if (out.series_[k].topic == s.name && out.series_[k].multi_id == s.multi_id) {
            found = static_cast<int>(k);
          }
        }
        if (found < 0) {
          TopicSeries ts;
          ts.topic = s.name;
          ts.multi_id = s.multi_id;
          for (const ulog::Column& c : s.columns) {
            if (!c.is_string()) ts.names.push_back(c.name);
          }
          ts.columns.resize(ts.names.size());
          found = static_cast<int>(out.series_.size());
          out.series_.push_back(std::move(ts));
        }
      }
      series_of.push_back(found);
      std::vector<const ulog::Column*> cols;
      if (found >= 0) {
        for (const std::string& n : out.series_[found].names) cols.push_back(s.FindColumn(n));
      }
      wanted.push_back(std::move(cols));
    }
    const int k = series_of[index];
    if (k < 0) return;
    TopicSeries& ts = out.series_[static_cast<std::size_t>(k)];
    ts.timestamp.push_back(m.timestamp);
    const auto& cols = wanted[index];
    for (std::size_t c = 0; c < ts.columns.size(); ++c) {
      ts.columns[c].push_back(cols[c] != nullptr ? m.Value(*cols[c])
                                                 : std::numeric_limits<double>::quiet_NaN());
    }
  });
  return out;
}

const TopicSeries* LogSeries::Find(std::string_view topic, std::uint8_t multi_id) const {
  for (const TopicSeries& s : series_) {
    if (s.topic == topic && s.multi_id == multi_id && !s.timestamp.empty()) return &s;
  }
  return nullptr;
}

const TopicSeries& LogSeries::Get(std::string_view topic, std::uint8_t multi_id) const {
  const TopicSeries* s = Find(topic, multi_id);
  if (s == nullptr) {
    throw std::runtime_error(file_ + ": no data of topic '" + std::string(topic) + "' (instance " +
                             std::to_string(multi_id) + ")");
  }
  return *s;
}

}  // namespace fnmpc::ulog

// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/core/sensors.hpp"

namespace fnmpc::experiment {

/// The scenario's faults as `fnmpc run` applies them (config::ScenarioFaults): measurement
/// filters (dropout windows, outliers) with their own seeded stream, the kill and motors-off
/// events, and what happened, for the summary's `faults` section.
class FaultInjector {
 public:
  FaultInjector(const config::ScenarioFaults& f, std::uint64_t seed)
      : f_(f), dropped_(f.sensor_dropouts.size(), 0) {
    std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                      0xFA17u};
    rng_.seed(seq);
  }

  /// False when the measurement is lost (dropout window); adds the outlier error otherwise.
  bool Filter(Measurement* m) {
    for (std::size_t w = 0; w < f_.sensor_dropouts.size(); ++w) {
      const config::SensorDropoutWindow& d = f_.sensor_dropouts[w];
      if (m->vehicle == d.index && m->kind == d.sensor && m->stamp >= d.from && m->stamp <= d.to) {
        ++dropped_[w];
        return false;
      }
    }
    ++measurements_;
    if (f_.outlier_rate > 0.0 && uniform_(rng_) < f_.outlier_rate) {
      AddOutlier(m);
      ++outliers_;
    }
    return true;
  }

  [[nodiscard]] long dropped(std::size_t w) const { return dropped_[w]; }
  [[nodiscard]] long measurements() const { return measurements_; }
  [[nodiscard]] long outliers() const { return outliers_; }

 private:
  /// An error of size s on every channel of the measurement, in the channel's unit: a random
  /// direction for vectors (norm s), a random sign for scalars.
  void AddOutlier(Measurement* m) {
    const double s = f_.outlier_size;
    auto dir = [this, s] {
      Vec3 u(normal_(rng_), normal_(rng_), normal_(rng_));
      const double n = u.norm();
      return n > 0.0 ? Vec3(s * u / n) : Vec3(s, 0.0, 0.0);
    };
    auto signed_size = [this, s] { return uniform_(rng_) < 0.5 ? -s : s; };
    switch (m->kind) {
      case SensorKind::kMocapPose:
        m->position += dir();
        m->euler += dir();
        m->euler.z() = WrapAngle(m->euler.z());
        break;
      case SensorKind::kImu:
        m->accel += dir();
        m->gyro += dir();
        break;
      case SensorKind::kOpticalFlow:
        m->velocity += dir();
        break;
      case SensorKind::kCompass:
        m->yaw = WrapAngle(m->yaw + signed_size());
        break;
      case SensorKind::kBattery:
        m->voltage += signed_size();
        break;
      case SensorKind::kRelative: {
        RelativeObservation& o = m->relative;
        o.range = std::abs(o.range + signed_size());
        o.bearing = WrapAngle(o.bearing + signed_size());
        o.elevation = std::clamp(o.elevation + signed_size(), -M_PI / 2, M_PI / 2);
        o.relative_yaw = WrapAngle(o.relative_yaw + signed_size());
        break;
      }
    }
  }

  const config::ScenarioFaults& f_;
  std::vector<long> dropped_;
  long measurements_ = 0, outliers_ = 0;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
};

}  // namespace fnmpc::experiment

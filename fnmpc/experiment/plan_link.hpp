// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <random>
#include <vector>

#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/formation/neighbour_plan.hpp"

/// The simulated link of cooperative mode (`controller.compensation: cooperative`, block
/// `link:`): each vehicle broadcasts its plan after every control step to the vehicles that
/// have it as a formation neighbour. A message occupies its sender's transmitter for its size
/// over the bandwidth (queued behind the one still being sent), arrives `latency` after its
/// transmission ends, and each receiver loses it with probability `loss_rate`. The loss draws
/// come from their own random stream seeded by the run seed (the world's streams are not
/// touched), in a fixed order: the same seed gives the same deliveries.
namespace fnmpc::experiment {

/// Messages of one run (summary.json `link`).
struct LinkStatistics {
  long sent = 0;       ///< plans broadcast
  long addressed = 0;  ///< (plan, receiver) pairs
  long lost = 0;       ///< pairs lost (loss_rate)
  long delivered = 0;  ///< pairs delivered
  long late = 0;       ///< delivered pairs already older than plan_timeout on arrival
};

class PlanLink {
 public:
  /// `receivers[i]`: the vehicles that have vehicle i as a formation neighbour.
  PlanLink(const config::LinkSettings& settings, std::vector<std::vector<int>> receivers,
           double plan_timeout, std::uint64_t seed);

  /// Vehicle m.vehicle broadcasts m at time t [s].
  void Send(const formation::PlanMessage& m, double t);
  /// Hands every message that has arrived by time t to deliver(receiver, message), in
  /// arrival order.
  template <class Receive>
  void Deliver(double t, const Receive& deliver) {
    while (!pending_.empty() && pending_.front().arrival <= t + 1e-9) {
      const Pending& p = pending_.front();
      ++stats_.delivered;
      if (p.arrival - p.message->stamp > plan_timeout_) ++stats_.late;
      deliver(p.receiver, *p.message);
      pending_.pop_front();
    }
  }
  [[nodiscard]] const LinkStatistics& statistics() const { return stats_; }

 private:
  struct Pending {
    double arrival;
    int receiver;
    std::shared_ptr<const formation::PlanMessage> message;
  };
  config::LinkSettings settings_;
  std::vector<std::vector<int>> receivers_;
  double plan_timeout_;
  std::mt19937_64 rng_;
  std::vector<double> busy_until_;  // per sender: end of its current transmission [s]
  std::deque<Pending> pending_;     // by arrival time
  LinkStatistics stats_;
};

}  // namespace fnmpc::experiment

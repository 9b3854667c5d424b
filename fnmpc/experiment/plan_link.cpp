// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/plan_link.hpp"

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <string>

namespace fnmpc::experiment {

namespace {
/// Mixed into the run seed: the link's stream differs from every other stream of the run.
constexpr std::uint64_t kLinkStream = 0x6c696e6b706c616eULL;  // "linkplan"
}  // namespace

PlanLink::PlanLink(const config::LinkSettings& settings, std::vector<std::vector<int>> receivers,
                   double plan_timeout, std::uint64_t seed)
    : settings_(settings),
      receivers_(std::move(receivers)),
      plan_timeout_(plan_timeout),
      rng_(seed ^ kLinkStream),
      busy_until_(receivers_.size(), -1e300) {
  if (!(settings_.latency >= 0.0) || !(settings_.loss_rate >= 0.0 && settings_.loss_rate <= 1.0) ||
      !(settings_.bandwidth > 0.0)) {
    throw std::invalid_argument("[PlanLink] need latency >= 0, loss_rate in [0, 1], bandwidth > 0");
  }
}

void PlanLink::Send(const formation::PlanMessage& m, double t) {
  if (m.vehicle < 0 || m.vehicle >= static_cast<int>(receivers_.size())) {
    throw std::invalid_argument("[PlanLink] plan of unknown vehicle " + std::to_string(m.vehicle));
  }
  ++stats_.sent;
  const auto i = static_cast<std::size_t>(m.vehicle);
  const double start = std::max(t, busy_until_[i]);
  busy_until_[i] = start + 8.0 * m.WireBytes() / settings_.bandwidth;
  const double arrival = busy_until_[i] + settings_.latency;
  const auto message = std::make_shared<const formation::PlanMessage>(m);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (const int r : receivers_[i]) {
    ++stats_.addressed;
    // One draw per pair whatever the rate, so that the stream does not depend on it.
    if (uniform(rng_) < settings_.loss_rate) {
      ++stats_.lost;
      continue;
    }
    // Sorted insertion (arrivals are almost always in order: from the back).
    auto it = pending_.end();
    while (it != pending_.begin() && std::prev(it)->arrival > arrival) --it;
    pending_.insert(it, Pending{arrival, r, message});
  }
}

}  // namespace fnmpc::experiment

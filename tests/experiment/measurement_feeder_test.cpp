// SPDX-License-Identifier: BSD-3-Clause
// The thread that feeds measurements to the controllers while the world
// steps processes each measurement once, in push order, and TakeRest hands over exactly the
// ones it has not processed.
#include "fnmpc/experiment/measurement_feeder.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace fnmpc::experiment {
namespace {

Measurement Numbered(int n) {
  Measurement m;
  m.vehicle = n % 7;
  m.stamp = n;
  return m;
}

TEST(MeasurementFeederTest, EveryMeasurementOnceInPushOrderByTheThreadOrTakeRest) {
  // Given a feeder with a ring of 4 whose sink holds the first measurement of each burst
  // until the producer has pushed the whole burst (so the ring fills and the others are
  // kept aside); the thread and TakeRest append to one list (the thread only before TakeRest
  // returns, TakeRest only after the thread's last one),
  std::vector<double> order;
  std::atomic<int> fed{0};
  std::atomic<bool> hold{false};
  std::size_t taken = 0;
  constexpr int kBurst = 1000;
  {
    MeasurementFeeder feeder(
        [&](const Measurement& m) {
          while (hold.load()) std::this_thread::yield();
          order.push_back(m.stamp);
          fed.fetch_add(1);
        },
        3);
    // when 20 bursts of 1000 are pushed, each ended by TakeRest once the thread fed some,
    for (int burst = 0; burst < 20; ++burst) {
      hold.store(true);
      for (int n = burst * kBurst; n < (burst + 1) * kBurst; ++n) feeder.Push(Numbered(n));
      const int fed_before = fed.load();
      hold.store(false);
      while (fed.load() == fed_before) std::this_thread::yield();
      const std::size_t before = taken;
      const std::uint32_t rest = feeder.TakeRest([&](const Measurement& m) {
        order.push_back(m.stamp);
        ++taken;
      });
      // then after each TakeRest every pushed measurement was fed or taken once,
      EXPECT_EQ(rest, taken - before);
      EXPECT_GE(rest, static_cast<std::uint32_t>(kBurst - 4));  // at most the ring's 4 fed
      ASSERT_EQ(order.size(), static_cast<std::size_t>((burst + 1) * kBurst));
      EXPECT_LE(feeder.ringed(), static_cast<std::uint32_t>((burst + 1) * kBurst));
    }
  }
  // in push order: 0, 1, 2, ... (the taken ones after the fed ones of their burst).
  for (std::size_t n = 0; n < order.size(); ++n) ASSERT_EQ(order[n], static_cast<double>(n)) << n;
  EXPECT_GE(fed.load(), 20);
}

TEST(MeasurementFeederTest, AThreadThatKeepsUpLeavesNothingToTake) {
  // Given a ring with room for a burst, when the thread has had the time to feed it all,
  std::atomic<int> fed{0};
  MeasurementFeeder feeder([&](const Measurement&) { fed.fetch_add(1); }, 256);
  for (int n = 0; n < 200; ++n) feeder.Push(Numbered(n));
  while (fed.load() < 200) std::this_thread::yield();
  // then TakeRest finds nothing left.
  EXPECT_EQ(feeder.TakeRest([](const Measurement&) {}), 0u);
  EXPECT_EQ(feeder.ringed(), 200u);
}

TEST(MeasurementFeederTest, TakeRestRethrowsTheSinksFirstErrorAndGoesOn) {
  // Given a sink that throws on measurements 3 and 5,
  std::vector<double> seen;
  std::atomic<int> calls{0};
  MeasurementFeeder feeder(
      [&](const Measurement& m) {
        calls.fetch_add(1);
        if (m.stamp == 3.0 || m.stamp == 5.0) {
          throw std::runtime_error("bad " + std::to_string(static_cast<int>(m.stamp)));
        }
        seen.push_back(m.stamp);
      },
      16);
  for (int n = 0; n < 8; ++n) feeder.Push(Numbered(n));
  // when the thread has had them all and the (empty) rest is taken,
  while (calls.load() < 8) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::uint32_t rest = 99;
  try {
    rest = feeder.TakeRest([](const Measurement&) {});
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    // then the first error comes back and the others were processed,
    EXPECT_STREQ(e.what(), "bad 3");
  }
  EXPECT_EQ(rest, 99u);
  EXPECT_EQ(seen, (std::vector<double>{0, 1, 2, 4, 6, 7}));
  // and a later TakeRest without a new error returns normally.
  feeder.Push(Numbered(8));
  EXPECT_NO_THROW(feeder.TakeRest([&](const Measurement& m) { seen.push_back(m.stamp); }));
  EXPECT_EQ(seen.back(), 8.0);
}

TEST(MeasurementFeederTest, WakesFromSleepAndStopsWhenDestroyedIdleOrNeverUsed) {
  // A feeder that never got a measurement stops when destroyed (the test would hang
  // otherwise),
  {
    MeasurementFeeder unused([](const Measurement&) {});
  }
  // and one whose thread went to sleep (idle for 50 ms) wakes for the next measurement.
  std::atomic<int> count{0};
  {
    MeasurementFeeder feeder([&](const Measurement&) { count.fetch_add(1); });
    feeder.Push(Numbered(0));
    while (count.load() < 1) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    EXPECT_EQ(feeder.TakeRest([](const Measurement&) {}), 0u);  // the thread fed it
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    feeder.Push(Numbered(1));
    while (count.load() < 2) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    EXPECT_EQ(feeder.TakeRest([](const Measurement&) {}), 0u);
  }
  EXPECT_EQ(count.load(), 2);
}

}  // namespace
}  // namespace fnmpc::experiment

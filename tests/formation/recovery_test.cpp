// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/formation/recovery.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace fnmpc::formation {
namespace {

RecoveryConfig Config() {
  RecoveryConfig c;
  c.fallbacks_before_reinit = 3;
  c.max_reinitialisations = 2;
  c.estimate_timeout = 0.5;
  return c;
}

TEST(RecoveryLadderTest, KConsecutiveFallbacksReinitialise) {
  RecoveryLadder l(Config());
  // Two fallbacks, a success, two more: never K in a row
  EXPECT_EQ(l.Update(0.00, true, true).action, RecoveryAction::kNone);
  EXPECT_EQ(l.Update(0.05, true, true).action, RecoveryAction::kNone);
  EXPECT_EQ(l.Update(0.10, true, false).action, RecoveryAction::kNone);
  EXPECT_EQ(l.Update(0.15, true, true).action, RecoveryAction::kNone);
  EXPECT_EQ(l.Update(0.20, true, true).action, RecoveryAction::kNone);
  // The third in a row asks for a re-initialisation, with its reason
  const RecoveryDecision d = l.Update(0.25, true, true);
  EXPECT_EQ(d.action, RecoveryAction::kReinitialise);
  EXPECT_EQ(d.reason, RecoveryReason::kConsecutiveFallbacks);
  EXPECT_EQ(l.reinitialisations(), 1);
  EXPECT_FALSE(l.failsafe());
}

TEST(RecoveryLadderTest, FailedReinitialisationsEndInFailsafe) {
  RecoveryLadder l(Config());
  int reinits = 0;
  RecoveryDecision last;
  double t = 0.0;
  // Fallbacks forever: K, re-init, K, re-init, K -> failsafe (max_reinitialisations = 2)
  for (int k = 0; k < 20 && !l.failsafe(); ++k, t += 0.05) {
    last = l.Update(t, true, true);
    if (last.action == RecoveryAction::kReinitialise) ++reinits;
  }
  EXPECT_EQ(reinits, 2);
  EXPECT_TRUE(l.failsafe());
  EXPECT_EQ(last.action, RecoveryAction::kFailsafe);
  EXPECT_EQ(last.reason, RecoveryReason::kReinitFailed);
  // Terminal: nothing more happens
  EXPECT_EQ(l.Update(t, true, false).action, RecoveryAction::kNone);
  EXPECT_TRUE(l.failsafe());
}

TEST(RecoveryLadderTest, SuccessAfterReinitialisationRestoresTheBudget) {
  RecoveryLadder l(Config());
  double t = 0.0;
  for (int round = 0; round < 5; ++round) {
    for (int k = 0; k < 3; ++k, t += 0.05) l.Update(t, true, true);
    l.Update(t, true, false);  // the re-initialised solver succeeds
    t += 0.05;
  }
  EXPECT_EQ(l.reinitialisations(), 5);
  EXPECT_FALSE(l.failsafe());
}

TEST(RecoveryLadderTest, UnusableEstimateForTimeoutTriggersFailsafe) {
  RecoveryLadder l(Config());
  // Unusable for 0.45 s, then usable: the timer restarts
  for (double t = 0.0; t < 0.46; t += 0.05)
    EXPECT_EQ(l.Update(t, false, false).action, RecoveryAction::kNone);
  EXPECT_EQ(l.Update(0.5, true, false).action, RecoveryAction::kNone);
  RecoveryDecision d;
  double t = 0.55;
  for (; t < 2.0 && d.action == RecoveryAction::kNone; t += 0.05) d = l.Update(t, false, false);
  EXPECT_EQ(d.action, RecoveryAction::kFailsafe);
  EXPECT_EQ(d.reason, RecoveryReason::kEstimateUnusable);
  EXPECT_NEAR(t - 0.05, 0.55 + 0.5, 1e-9);
}

TEST(RecoveryLadderTest, InvalidConfigNamesTheField) {
  RecoveryConfig c = Config();
  c.fallbacks_before_reinit = 0;
  try {
    RecoveryLadder l(c);
    FAIL() << "accepted fallbacks_before_reinit = 0";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fallbacks_before_reinit"), std::string::npos);
  }
  c = Config();
  c.estimate_timeout = 0.0;
  EXPECT_THROW(RecoveryLadder{c}, std::invalid_argument);
}

TEST(SafetyConfigTest, CollisionSigmasAreTheNormalQuantileOfTheConfidence) {
  // Phi^-1 of the one-sided confidence (tables: 0.8413 -> 1, 0.95 -> 1.6449, 0.975 -> 1.9600)
  SafetyConfig s;
  s.collision_confidence = 0.5;
  EXPECT_EQ(CollisionSigmas(s), 0.0);
  s.collision_confidence = 0.841345;
  EXPECT_NEAR(CollisionSigmas(s), 1.0, 1e-4);
  s.collision_confidence = 0.95;
  EXPECT_NEAR(CollisionSigmas(s), 1.6449, 1e-4);
  s.collision_confidence = 0.975;
  EXPECT_NEAR(CollisionSigmas(s), 1.9600, 1e-4);
  // and a confidence outside [0.5, 1) is refused by name
  for (const double bad : {0.4, 1.0, std::nan("")}) {
    s.collision_confidence = bad;
    try {
      s.Validate();
      FAIL() << "accepted collision_confidence = " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("collision_confidence"), std::string::npos);
    }
  }
}

}  // namespace
}  // namespace fnmpc::formation

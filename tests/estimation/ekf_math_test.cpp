// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/estimation/ekf_math.hpp"

#include <gtest/gtest.h>

#include <random>

#include "fnmpc/core/rotation.hpp"
#include "fnmpc/estimation/neighbour_ekf.hpp"
#include "fnmpc/estimation/replay_buffer.hpp"
#include "fnmpc/estimation/vehicle_ekf.hpp"
#include "tests/support/numeric_jacobian.hpp"

namespace fnmpc::estimation {
namespace {

TEST(Chi2Test, QuantilesMatchTables) {
  // Given reference values of the chi-square quantiles (standard tables)
  // When computed / Then they agree to 1e-3
  EXPECT_NEAR(Chi2Quantile(0.95, 1), 3.841, 1e-3);
  EXPECT_NEAR(Chi2Quantile(0.95, 2), 5.991, 1e-3);
  EXPECT_NEAR(Chi2Quantile(0.95, 3), 7.815, 1e-3);
  EXPECT_NEAR(Chi2Quantile(0.99, 4), 13.277, 1e-3);
  EXPECT_NEAR(Chi2Quantile(0.999, 6), 22.458, 1e-3);
  EXPECT_NEAR(Chi2Quantile(0.025, 100), 74.222, 1e-3);
  EXPECT_NEAR(Chi2Quantile(0.975, 100), 129.561, 1e-3);
  EXPECT_NEAR(Chi2Survival(Chi2Quantile(0.3, 7), 7), 0.7, 1e-9);
  EXPECT_THROW(Chi2Quantile(1.0, 3), std::invalid_argument);
  EXPECT_THROW(Chi2Quantile(0.5, 0), std::invalid_argument);
}

TEST(RotationPartialsTest, MatchFiniteDifferences) {
  // Given an attitude away from singularities
  const Vec3 e(0.3, -0.2, 2.5);
  Mat3 R;
  std::array<Mat3, 3> dR;
  // When the partials are computed
  RotationZyxPartials(e, &R, &dR);
  // Then R matches RotationZyx and each partial matches central differences
  EXPECT_LT((R - RotationZyx(e.x(), e.y(), e.z())).norm(), 1e-14);
  for (int i = 0; i < 3; ++i) {
    Vec3 ep = e, em = e;
    ep(i) += 1e-6;
    em(i) -= 1e-6;
    const Mat3 fd =
        (RotationZyx(ep.x(), ep.y(), ep.z()) - RotationZyx(em.x(), em.y(), em.z())) / 2e-6;
    EXPECT_LT((fd - dR[static_cast<std::size_t>(i)]).norm(), 1e-8) << "axis " << i;
  }
}

TEST(KalmanUpdateTest, JosephFormKeepsCovarianceSymmetricPositiveDefinite) {
  // Given a 3-state prior with a tiny, nearly singular covariance and a very precise sensor
  Vec<3> x(1.0, 2.0, 3.0);
  Mat<3, 3> P;
  P << 1e-2, 0.99e-2, 0, 0.99e-2, 1e-2, 0, 0, 0, 1e-8;
  const Mat<2, 3> H = (Mat<2, 3>() << 1, 0, 0, 0, 1, 1).finished();
  const Mat<2, 2> R = Mat<2, 2>::Identity() * 1e-12;
  // When fused repeatedly
  for (int k = 0; k < 100; ++k) {
    const Vec<2> y(1e-4 * ((k % 3) - 1.0), -1e-4);
    const UpdateResult r = KalmanUpdate<3, 2>(y, H, R, kInf, &x, &P);
    ASSERT_EQ(r.status, EkfStatus::kAccepted);
  }
  // Then P stays exactly symmetric and positive definite
  EXPECT_EQ((P - P.transpose()).norm(), 0.0);
  const Eigen::LLT<Mat<3, 3>> llt(P);
  EXPECT_EQ(llt.info(), Eigen::Success);
}

TEST(SymmetrizeTest, InPlaceGivesTheBitsOfTheHalfSum) {
  // Given random non-symmetric matrices of the estimators' sizes, with entries of many scales
  std::mt19937 rng(23);
  std::normal_distribution<double> g;
  std::uniform_int_distribution<int> scale(-12, 12);
  for (int trial = 0; trial < 200; ++trial) {
    Mat<18, 18> P;
    for (int i = 0; i < 18; ++i)
      for (int j = 0; j < 18; ++j) P(i, j) = g(rng) * std::ldexp(1.0, scale(rng));
    const Mat<18, 18> half_sum = (0.5 * (P + P.transpose())).eval();
    // When symmetrized in place
    Symmetrize<18>(&P);
    // Then every entry has the bits of (P + P') / 2, the diagonal included
    for (int i = 0; i < 18; ++i)
      for (int j = 0; j < 18; ++j) ASSERT_EQ(P(i, j), half_sum(i, j)) << i << ", " << j;
  }
}

TEST(KalmanUpdateTest, GateRejectsWithoutTouchingState) {
  // Given a unit prior and a 10-sigma innovation
  Vec<1> x(0.0);
  Mat<1, 1> P(1.0);
  // When gated at the 99.999 % chi-square(1) quantile
  const UpdateResult r = KalmanUpdate<1, 1>(Vec<1>(10.0), Mat<1, 1>(1.0), Mat<1, 1>(1.0),
                                            Chi2Quantile(0.99999, 1), &x, &P);
  // Then it is rejected with the NIS reported and the state untouched
  EXPECT_EQ(r.status, EkfStatus::kRejectedGated);
  EXPECT_NEAR(r.nis, 50.0, 1e-12);
  EXPECT_EQ(x(0), 0.0);
  EXPECT_EQ(P(0, 0), 1.0);
}

// A scalar "filter" for testing the replay buffer: the state is a running hash of the
// events in application order, so any ordering difference shows.
struct ToyEvent {
  double stamp = 0.0;
  int order = 0;
  double value = 0.0;
};
struct ToyState {
  double time = kNaN;
  double hash = 0.0;
};

EkfStatus ToyApply(const ToyEvent& e, ToyState* s) {
  s->hash = s->hash * 1.000001 + e.value * (1.0 + e.stamp);
  s->time = e.stamp;
  return e.value > 100.0 ? EkfStatus::kRejectedGated : EkfStatus::kAccepted;
}

TEST(ReplayBufferTest, OutOfOrderDeliveryEqualsInOrder) {
  // Given 200 events and a random delivery delay of up to 0.05 s
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> delay(0.0, 0.05);
  std::vector<std::pair<double, ToyEvent>> events;
  for (int k = 0; k < 200; ++k) {
    const ToyEvent e{0.01 * k, k % 2, static_cast<double>(k % 17)};
    events.emplace_back(e.stamp + delay(rng), e);
  }
  ReplayBuffer<ToyEvent, ToyState> in_order(64, 0.2), shuffled(64, 0.2);
  ToyState a, b;
  const auto recount = [](const ToyEvent&, EkfStatus, EkfStatus) {};
  // When delivered by stamp and by arrival
  for (const auto& [arrival, e] : events) in_order.Submit(e, &a, ToyApply, recount);
  std::stable_sort(events.begin(), events.end(),
                   [](const auto& l, const auto& r) { return l.first < r.first; });
  for (const auto& [arrival, e] : events) {
    ASSERT_EQ(shuffled.Submit(e, &b, ToyApply, recount), EkfStatus::kAccepted);
  }
  // Then the final states agree exactly and replays happened
  EXPECT_EQ(a.hash, b.hash);
  EXPECT_GT(shuffled.replays(), 0);
  EXPECT_EQ(in_order.replays(), 0);
  // And an event older than the lag is refused
  EXPECT_EQ(shuffled.Submit(ToyEvent{1.0, 0, 1.0}, &b, ToyApply, recount),
            EkfStatus::kRejectedTooOld);
}

TEST(ReplayBufferTest, CapacityEvictsOldestAndCounts) {
  // Given a buffer of 4 slots and a long lag
  ReplayBuffer<ToyEvent, ToyState> buf(4, 10.0);
  ToyState s;
  const auto recount = [](const ToyEvent&, EkfStatus, EkfStatus) {};
  // When 10 in-order events are submitted
  for (int k = 0; k < 10; ++k) buf.Submit(ToyEvent{1.0 * k, 0, 1.0}, &s, ToyApply, recount);
  // Then only 4 are kept, 6 evictions counted, and an event before the kept window is refused
  EXPECT_EQ(buf.size(), 4);
  EXPECT_EQ(buf.overflows(), 6);
  EXPECT_EQ(buf.Submit(ToyEvent{4.5, 0, 1.0}, &s, ToyApply, recount), EkfStatus::kRejectedTooOld);
}

// ---------------------------------------------------------------------------------------
// Model Jacobians against central differences.

using ::fnmpc::testing::NumericJacobian;

VehicleStateVec SampleVehicleState() {
  VehicleStateVec x;
  x << 1.0, -2.0, 3.0, 0.4, -0.3, 0.2, 0.15, -0.1, 2.8, 0.05, -0.02, 0.1, 0.01, -0.02, 0.005, 0.3,
      -0.7, 1.1;
  return x;
}

TEST(VehicleModelTest, ImuFlowJacobianMatchesFiniteDifferences) {
  // Given a generic state and IMU input
  const VehicleStateVec x = SampleVehicleState();
  const Vec3 f(0.5, -0.3, 9.9), w(0.2, -0.4, 0.3);
  // When / Then
  const VehicleStateCov fd = NumericJacobian<VehicleStateIndex::kSize>(
      x, [&](const VehicleStateVec& z) { return ImuFlow(z, f, w); });
  EXPECT_LT((fd - ImuFlowJacobian(x, f, w)).cwiseAbs().maxCoeff(), 1e-7);
}

TEST(VehicleModelTest, CommandFlowJacobianMatchesFiniteDifferences) {
  // Given a calibrated vehicle and a command
  model::VehicleParams vp;
  vp.bias.roll = 0.01;
  vp.bias.thrust_scale = 0.97;
  const VehicleStateVec x = SampleVehicleState();
  const Vec3 refs(0.1, -0.05, 2.9);
  // When / Then
  const VehicleStateCov fd = NumericJacobian<VehicleStateIndex::kSize>(
      x, [&](const VehicleStateVec& z) { return CommandFlow(z, 14.0, refs, vp); });
  EXPECT_LT((fd - CommandFlowJacobian(x, 14.0, refs, vp)).cwiseAbs().maxCoeff(), 1e-7);
  // And at equilibrium attitude with hover thrust, the vertical acceleration vanishes
  VehicleStateVec level = VehicleStateVec::Zero();
  level(VehicleStateIndex::kEuler + 2) = 0.0;
  const VehicleStateVec f0 = CommandFlow(level, vp.mass * kGravity / 0.97, Vec3(-0.01, 0, 0), vp);
  EXPECT_NEAR(f0(VehicleStateIndex::kVel + 2), 0.0, 1e-12);
}

TEST(VehicleModelTest, LandedAccelJacobianMatchesFiniteDifferences) {
  const VehicleStateVec x = SampleVehicleState();
  Mat<3, VehicleStateIndex::kSize> fd;
  for (int i = 0; i < VehicleStateIndex::kSize; ++i) {
    VehicleStateVec xp = x, xm = x;
    xp(i) += 1e-6;
    xm(i) -= 1e-6;
    fd.col(i) = (LandedAccel(xp) - LandedAccel(xm)) / 2e-6;
  }
  EXPECT_LT((fd - LandedAccelJacobian(x)).cwiseAbs().maxCoeff(), 1e-7);
  // And level at rest the accelerometer reads +g along body z
  EXPECT_NEAR((LandedAccel(VehicleStateVec::Zero()) - Vec3(0, 0, kGravity)).norm(), 0.0, 1e-15);
}

TEST(VehicleModelTest, ExternalAccelerationEntersCommandFlowAndIsWhatTheImuLeavesUnexplained) {
  // Given a tilted vehicle with an external acceleration d in its state
  model::VehicleParams vp;
  vp.bias.thrust_scale = 0.97;
  const VehicleStateVec x = SampleVehicleState();
  const Vec3 d = x.segment<3>(VehicleStateIndex::kDisturbance);
  const double thrust = 14.0;
  // When the command model's acceleration is what the accelerometer senses (specific force
  // R' (a + g e3) plus the accelerometer bias)
  const VehicleStateVec f = CommandFlow(x, thrust, Vec3(0.1, -0.05, 2.9), vp);
  const Vec3 a = f.segment<3>(VehicleStateIndex::kVel);
  const Vec3 e = x.segment<3>(VehicleStateIndex::kEuler);
  const Mat3 R = RotationZyx(e.x(), e.y(), e.z());
  const Vec3 specific =
      R.transpose() * (a + Vec3(0, 0, kGravity)) + x.segment<3>(VehicleStateIndex::kAccelBias);
  // Then the acceleration the thrust model leaves unexplained is exactly d
  EXPECT_LT((UnexplainedAcceleration(x, specific, thrust, vp) - d).norm(), 1e-12);
  // And d enters v' one to one, and nothing else
  VehicleStateVec x0 = x;
  x0.segment<3>(VehicleStateIndex::kDisturbance).setZero();
  const VehicleStateVec diff = f - CommandFlow(x0, thrust, Vec3(0.1, -0.05, 2.9), vp);
  EXPECT_LT((diff.segment<3>(VehicleStateIndex::kVel) - d).norm(), 1e-12);
  EXPECT_LT(diff.norm() - d.norm(), 1e-12);
  // And the IMU model leaves d constant (a random walk: f = 0 in its rows)
  EXPECT_EQ(ImuFlow(x, specific, Vec3(0.1, 0.2, 0.3))
                .segment<3>(VehicleStateIndex::kDisturbance)
                .cwiseAbs()
                .maxCoeff(),
            0.0);
}

TEST(NeighbourModelTest, RelativeJacobiansMatchFiniteDifferences) {
  // Given a neighbour offset and an observer attitude
  NeighbourStateVec x;
  x << 2.0, -1.0, 0.5, 0.3, 0.1, 0.0, 1.0, 0.2;
  const Vec3 e(0.1, -0.05, 0.7);
  // When / Then: state Jacobian
  Mat<4, 8> fd;
  for (int i = 0; i < 8; ++i) {
    NeighbourStateVec xp = x, xm = x;
    xp(i) += 1e-6;
    xm(i) -= 1e-6;
    fd.col(i) = (RelativeMeasurementModel(xp, e) - RelativeMeasurementModel(xm, e)) / 2e-6;
  }
  EXPECT_LT((fd - RelativeMeasurementJacobian(x, e)).cwiseAbs().maxCoeff(), 1e-7);
  // And own-attitude Jacobian
  Mat<4, 3> fe;
  for (int i = 0; i < 3; ++i) {
    Vec3 ep = e, em = e;
    ep(i) += 1e-6;
    em(i) -= 1e-6;
    fe.col(i) = (RelativeMeasurementModel(x, ep) - RelativeMeasurementModel(x, em)) / 2e-6;
  }
  EXPECT_LT((fe - RelativeMeasurementOwnAttitudeJacobian(x, e)).cwiseAbs().maxCoeff(), 1e-7);
}

}  // namespace
}  // namespace fnmpc::estimation

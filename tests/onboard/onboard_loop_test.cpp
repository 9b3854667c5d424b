// SPDX-License-Identifier: BSD-3-Clause
// The onboard loop allocates nothing once built: each control step decodes the autopilot's
// state from a MAVLink byte stream (LOCAL_POSITION_NED, ATTITUDE), runs the formation
// controller of a leader and a follower from take-off through NMPC flight to landing, and
// encodes the command as SET_ATTITUDE_TARGET, which the autopilot side parses back.
// tests/support/malloc_counter.hpp counts every C allocation call (operator new included).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <variant>
#include <vector>

#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/mavlink/encoder.hpp"
#include "fnmpc/mavlink/frame_conversions.hpp"
#include "fnmpc/mavlink/parser.hpp"
#include "tests/formation/controller_test_support.hpp"
#include "tests/support/malloc_counter.hpp"

namespace fnmpc::formation {
namespace {

using testing::BaseConfig;
using testing::kGround;
using testing::kTs;
using testing::Plant;

// One vehicle's end of the link: its autopilot's encoder and the onboard computer's parser
// (state in), the onboard computer's encoder and the autopilot's parser (command out).
struct Link {
  mavlink::Encoder autopilot{1, 1};
  mavlink::Encoder onboard{1, 191};
  mavlink::Parser onboard_rx;
  mavlink::Parser autopilot_rx;
  std::array<std::uint8_t, mavlink::kMaxFrameLength> buffer{};
  long state_frames = 0, command_frames = 0;

  // Autopilot -> onboard: the plant's position, velocity and attitude; returns the estimate
  // the onboard side decodes (float precision, back in ENU).
  estimation::VehicleEstimate SendState(const Plant& p, double t) {
    estimation::VehicleEstimate e = p.Estimate(t);
    mavlink::LocalPositionNed pos;
    pos.time_boot_ms = static_cast<std::uint32_t>(std::lround(1e3 * t));
    const Vec3 p_ned = mavlink::EnuToNed(p.x.head<3>());
    const Vec3 v_ned = mavlink::EnuToNed(p.x.segment<3>(3));
    pos.x = static_cast<float>(p_ned.x());
    pos.y = static_cast<float>(p_ned.y());
    pos.z = static_cast<float>(p_ned.z());
    pos.vx = static_cast<float>(v_ned.x());
    pos.vy = static_cast<float>(v_ned.y());
    pos.vz = static_cast<float>(v_ned.z());
    mavlink::Attitude att;
    att.time_boot_ms = pos.time_boot_ms;
    const Vec3 rpy = mavlink::EulerEnuFluToNedFrd(p.x.tail<3>());
    att.roll = static_cast<float>(rpy.x());
    att.pitch = static_cast<float>(rpy.y());
    att.yaw = static_cast<float>(rpy.z());
    auto on_frame = [&](const mavlink::Frame& f) {
      if (const auto* m = std::get_if<mavlink::LocalPositionNed>(&f.message)) {
        e.position = mavlink::NedToEnu(Vec3(m->x, m->y, m->z));
        e.velocity = mavlink::NedToEnu(Vec3(m->vx, m->vy, m->vz));
        ++state_frames;
      } else if (const auto* a = std::get_if<mavlink::Attitude>(&f.message)) {
        e.euler = mavlink::EulerNedFrdToEnuFlu(Vec3(a->roll, a->pitch, a->yaw));
        ++state_frames;
      }
    };
    for (const mavlink::Message& m : {mavlink::Message(pos), mavlink::Message(att)}) {
      const std::size_t n = autopilot.Encode(m, buffer);
      onboard_rx.Parse(std::span<const std::uint8_t>(buffer.data(), n), on_frame);
    }
    return e;
  }

  // Onboard -> autopilot: the command as SET_ATTITUDE_TARGET (attitude and normalised
  // thrust); returns the thrust the autopilot decodes.
  double SendCommand(const ControlOutput& o, double t) {
    mavlink::SetAttitudeTarget cmd;
    cmd.time_boot_ms = static_cast<std::uint32_t>(std::lround(1e3 * t));
    const Vec3 rpy = mavlink::EulerEnuFluToNedFrd(Vec3(o.roll, o.pitch, o.yaw));
    const Eigen::Quaterniond q = Eigen::AngleAxisd(rpy.z(), Vec3::UnitZ()) *
                                 Eigen::AngleAxisd(rpy.y(), Vec3::UnitY()) *
                                 Eigen::AngleAxisd(rpy.x(), Vec3::UnitX());
    cmd.q = mavlink::QuaternionToWxyz(q);
    cmd.thrust = static_cast<float>(std::isfinite(o.throttle) ? o.throttle : o.thrust / 30.0);
    cmd.type_mask = 0x07;  // ignore the body rates
    double received = kNaN;
    const std::size_t n = onboard.Encode(cmd, buffer);
    autopilot_rx.Parse(std::span<const std::uint8_t>(buffer.data(), n),
                       [&](const mavlink::Frame& f) {
                         if (const auto* m = std::get_if<mavlink::SetAttitudeTarget>(&f.message)) {
                           received = m->thrust;
                           ++command_frames;
                         }
                       });
    return received;
  }
};

TEST(OnboardLoopTest, DecodeControlEncodeAllocatesNothingFromTakeoffToLanding) {
  // Given a leader and a follower with their links, built (all allocation happens here)
  ControllerConfig lc = BaseConfig(true);
  lc.landing_time = 9.0;
  ControllerConfig fc = BaseConfig(false);
  fc.landing_time = 12.0;
  VehicleController leader(lc), follower(fc);
  Plant pl, pf;
  Link ll, lf;
  std::vector<estimation::NeighbourStateVec> nb(1);
  int steps = 0, nmpc_steps = 0, thrust_mismatches = 0;
  // When both fly 16 s of take-off, NMPC and landing through their links
  const long n = ::fnmpc::testing::CountMallocs([&] {
    for (int k = 0; k * kTs <= 16.0; ++k) {
      const double t = k * kTs;
      ControlOutput o = leader.ControlWithEstimates(t, ll.SendState(pl, t), {});
      leader.Diagnose(&o);
      const double lt = ll.SendCommand(o, t);
      pl.Step(o);
      estimation::VehicleEstimate e = lf.SendState(pf, t);
      e.position.z() -= kGround;
      nb[0].setZero();
      nb[0].head<3>() = pl.x.head<3>() - pf.x.head<3>();
      nb[0].segment<3>(3) = pl.x.segment<3>(3);
      ControlOutput f = follower.ControlWithEstimates(t, e, nb);
      follower.Diagnose(&f);
      const double ft = lf.SendCommand(f, t);
      pf.Step(f);
      ++steps;
      nmpc_steps += (o.phase == FlightPhase::kNmpc) + (f.phase == FlightPhase::kNmpc);
      const double l_sent = std::isfinite(o.throttle) ? o.throttle : o.thrust / 30.0;
      const double f_sent = std::isfinite(f.throttle) ? f.throttle : f.thrust / 30.0;
      thrust_mismatches += std::abs(lt - l_sent) > 1e-6 || std::abs(ft - f_sent) > 1e-6;
    }
  });
  // Then no C allocation call was made, every frame came through, both flew NMPC and landed
  EXPECT_EQ(n, 0);
  EXPECT_EQ(ll.state_frames + lf.state_frames, 4L * steps);
  EXPECT_EQ(ll.command_frames + lf.command_frames, 2L * steps);
  EXPECT_EQ(thrust_mismatches, 0);
  EXPECT_GT(nmpc_steps, 100);
  EXPECT_EQ(leader.phase(), FlightPhase::kLanded);
  EXPECT_EQ(follower.phase(), FlightPhase::kLanded);
}

TEST(OnboardLoopTest, TheCounterSeesAnAllocationInTheLoop) {
  // The check can fail: the same loop with a std::vector made inside is counted.
  VehicleController leader(BaseConfig(true));
  Plant pl;
  Link ll;
  const long n = ::fnmpc::testing::CountMallocs([&] {
    for (int k = 0; k < 10; ++k) {
      const double t = k * kTs;
      std::vector<estimation::NeighbourStateVec> none(1);
      ControlOutput o = leader.ControlWithEstimates(t, ll.SendState(pl, t), {});
      ll.SendCommand(o, t);
      pl.Step(o);
    }
  });
  EXPECT_GE(n, 10);
}

}  // namespace
}  // namespace fnmpc::formation

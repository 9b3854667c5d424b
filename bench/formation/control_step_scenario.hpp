// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The control-step scenario shared by controller_bench (wall time) and controller_step_count
// (instruction counts under callgrind): a follower with 2 neighbours hovering in formation
// in the NMPC phase, on the NMPC's own model as plant.
#include <vector>

#include "fnmpc/formation/vehicle_controller.hpp"
#include "tests/formation/controller_test_support.hpp"

namespace fnmpc::bench {

/// rate: input-rate weights on; close: the second neighbour 0.4 m away (inside r_min = 0.45,
/// the collision row active) instead of 3 m. observer: Compensation::kObserver with a
/// constant push d on the plant that the estimate reports (hover targets and the acceleration
/// parameter in use). wake: Compensation::kWake with neighbour 0 hovering 0.8 m above and
/// 0.25 m beside (the follower in its wake: both wake slots in use, one with a push).
/// Neighbour 0 is the leader (depth 0), neighbour 1 a row-mate (depth 1), as in the triangle.
struct ControlStepVariant {
  bool rate = false, close = false, observer = false, wake = false;
};

class ControlStepScenario {
 public:
  explicit ControlStepScenario(ControlStepVariant v) : ctrl_(Config(&v)), v_(v) {
    nb_.resize(2);
    d_ = v_.observer ? Vec3(0.3, -0.2, -0.6) : Vec3(Vec3::Zero());
    // Take-off, switch and settling (12 s): the measured steps are in steady NMPC flight.
    while (ctrl_.phase() != formation::FlightPhase::kNmpc || t_ < 12.0) Step();
  }

  /// One control step (ControlWithEstimates) and the plant's step under its command.
  formation::ControlOutput Step() {
    return Step([](auto&& control) { return control(); });
  }

  /// The same, with the controller's call alone passed through `around` (a callable taking
  /// the call and returning its ControlOutput): controller_bench times the control step
  /// there, without the scenario's plant step and estimate synthesis.
  template <class Around>
  formation::ControlOutput Step(Around&& around) {
    namespace ft = formation::testing;
    estimation::VehicleEstimate e = plant_.Estimate(t_);
    e.position.z() -= ft::kGround;
    e.disturbance = d_;
    nb_[0].setZero();
    nb_[0].head<3>() = p0_ - plant_.x.head<3>();
    nb_[1].setZero();
    nb_[1].head<3>() = p1_ - plant_.x.head<3>();
    const formation::ControlOutput o =
        around([&]() { return ctrl_.ControlWithEstimates(t_, e, nb_); });
    plant_.Step(o);
    // The push over the step: exactly its double integral (v' gains d, nothing else).
    plant_.x.head<3>() += 0.5 * ft::kTs * ft::kTs * d_;
    plant_.x.segment<3>(3) += ft::kTs * d_;
    t_ += ft::kTs;
    return o;
  }

  [[nodiscard]] const formation::VehicleController& controller() const { return ctrl_; }

 private:
  formation::ControllerConfig Config(ControlStepVariant* v) {
    using formation::Compensation;
    formation::ControllerConfig c = formation::testing::BaseConfig(false);
    p0_ = v->wake ? Vec3(0.25, 0.0, 1.9) : Vec3(1.3, -0.8, 1.1);
    p1_ = v->close ? Vec3(0.0, 0.4, 1.1) : Vec3(-1.7, -3.8, 1.1);
    // The triangle's depths (the leader, a row-mate): the tie-disagreement discount acts.
    c.neighbours = {{0, p0_ - Vec3(0.0, 0.0, 1.1), 0}, {2, p1_ - Vec3(0.0, 0.0, 1.1), 1}};
    v->observer = v->observer || v->wake;
    if (v->rate) {
      c.weights.thrust_rate = 2.0;
      c.weights.attitude_ref_rate = 50.0;
    }
    if (v->observer) c.compensation = v->wake ? Compensation::kWake : Compensation::kObserver;
    return c;
  }

  Vec3 p0_ = Vec3::Zero(), p1_ = Vec3::Zero(), d_ = Vec3::Zero();
  formation::VehicleController ctrl_;
  ControlStepVariant v_;
  formation::testing::Plant plant_;
  std::vector<estimation::NeighbourStateVec> nb_;
  double t_ = 0.0;
};

}  // namespace fnmpc::bench

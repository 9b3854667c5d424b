// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/run_loop.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string_view>

#include "fnmpc/config/output_files.hpp"
#include "fnmpc/experiment/fault_injector.hpp"
#include "fnmpc/experiment/measurement_feeder.hpp"
#include "fnmpc/experiment/plan_link.hpp"
#include "fnmpc/experiment/run_log.hpp"
#include "fnmpc/experiment/worker_pool.hpp"
#include "fnmpc/formation/trajectory.hpp"
#include "fnmpc/formation/vehicle_controller.hpp"
#include "fnmpc/sim/world.hpp"

namespace fnmpc::experiment {

using formation::FlightPhase;

RunRecord RunClosedLoop(const config::ScenarioConfig& sc, const RunOptions& options,
                        const std::string& dir) {
  const double duration = options.duration > 0.0 ? options.duration : sc.duration;
  const bool manual = sc.leader_mode == "manual";
  const int nv = static_cast<int>(sc.vehicles.size());
  const formation::WaypointTrajectory trajectory = onboard::LeaderTrajectory(sc, options.seed);

  // ---- World. The autopilots' command-timeout failsafe is on: a vehicle whose controller
  // stops (fault kill_controller) is landed by its autopilot, as a real one would.
  sim::WorldConfig world_config = WorldConfigFor(sc, options.seed);
  world_config.command_timeout.enabled = true;
  sim::World world(world_config);
  const config::ScenarioFaults& faults = sc.faults;
  FaultInjector injector(faults, options.seed);
  std::vector<char> killed(nv, 0);
  std::vector<double> prev_vz(nv, 0.0);

  // ---- Controllers (a manually moved leader has none).
  std::vector<std::unique_ptr<formation::VehicleController>> ctrl(nv);
  for (int i = 0; i < nv; ++i) {
    if (manual && i == sc.leader) continue;
    formation::ControllerConfig cc = onboard::ControllerConfigFor(sc, i, trajectory);
    cc.safety.injected_failure_rate = faults.solver_failure_rate;  // 0: off
    cc.safety.injected_failure_seed = options.seed;
    ctrl[i] = std::make_unique<formation::VehicleController>(cc);
  }

  // ---- Cooperative mode: the plans go over the simulated link to the vehicles that have
  // their publisher as a formation neighbour.
  std::unique_ptr<PlanLink> link;
  if (sc.compensation >= formation::Compensation::kCooperative) {
    std::vector<std::vector<int>> receivers(static_cast<std::size_t>(nv));
    for (int r = 0; r < nv; ++r) {
      if (!ctrl[r]) continue;
      for (const formation::NeighbourTarget& n : ctrl[r]->config().neighbours) {
        receivers[static_cast<std::size_t>(n.vehicle)].push_back(r);
      }
    }
    link = std::make_unique<PlanLink>(sc.link, std::move(receivers), sc.plan_timeout, options.seed);
  }
  formation::PlanMessage plan;

  // ---- Logs.
  std::filesystem::create_directories(dir);
  if (sc.reality.enabled) WritePlantFiles(sc, world_config, dir);
  RunRecord rec;
  rec.duration = duration;
  rec.vehicles.resize(nv);
  rec.downed.resize(nv);
  rec.pairs.resize(static_cast<std::size_t>(nv) * static_cast<std::size_t>(nv - 1) / 2);
  std::vector<VehicleCsvLog> csv;
  csv.reserve(nv);
  for (int i = 0; i < nv; ++i) {
    const auto& v = sc.vehicles[i];
    VehicleRecord& L = rec.vehicles[i];
    csv.emplace_back(config::PathInside(dir, v.name + ".csv"));
    L.nb_errors.resize(v.neighbours.size());
    L.nb_steady.resize(v.neighbours.size());
  }

  const double dt = world.physics_dt();
  if (!(std::isfinite(duration) && duration > 0.0 && duration <= config::kMaxScenarioDuration)) {
    throw std::invalid_argument("[RunScenario] duration must be in (0, " +
                                std::to_string(config::kMaxScenarioDuration) + "] s, got " +
                                std::to_string(duration));
  }
  const int steps = static_cast<int>(std::lround(duration / dt));
  const int every = std::max(1, static_cast<int>(std::lround(sc.rti.sample_time / dt)));
  std::vector<formation::ControlOutput> prev(nv);
  Measurement m;
  int next_progress = 0;
  // Each vehicle's measurements since its last control step, in delivery order: its own
  // thread feeds them to its controller just before the step (the same calls in the same
  // order as feeding them at delivery: nothing else reaches a controller in between).
  std::vector<std::vector<Measurement>> inbox(static_cast<std::size_t>(nv));
  const auto feed = [&](int i) {
    if (ctrl[i] && !killed[i]) {
      for (const Measurement& x : inbox[i]) ctrl[i]->Process(x);
    }
    inbox[i].clear();
  };
  // The vehicles' estimators and controllers of one control step run on these threads; each
  // task touches only its own vehicle's controller, inbox and output.
  WorkerPool pool(std::max(1, std::min(options.threads, nv)));
  // With more than one thread, a thread of its own feeds the measurements to the controllers
  // while the world takes its next steps (in delivery order, so each controller gets the same
  // calls as from the inboxes); at a control step the ones it has not reached go to the
  // inboxes, which the vehicles' tasks empty in parallel.
  std::optional<MeasurementFeeder> feeder;
  if (pool.threads() > 1) {
    feeder.emplace([&](const Measurement& x) { ctrl[x.vehicle]->Process(x); });
  }
  std::vector<formation::ControlOutput> outs(static_cast<std::size_t>(nv));
  std::vector<char> killed_now(static_cast<std::size_t>(nv), 0);
  std::vector<sim::TrueState> truth(static_cast<std::size_t>(nv));  // at each control step
  std::vector<Vec3> positions(static_cast<std::size_t>(nv));

  for (int step = 0; step <= steps; ++step) {
    if (options.stop != nullptr && *options.stop != 0) {
      rec.stopped = "interrupted";
      break;
    }
    const double t = world.time();
    if (manual) {
      Vec3 p, v;
      trajectory.Sample(t - sc.trajectory_start, &p, &v);
      world.SetState(sc.leader, sc.manual_start + p, Vec3(0, 0, sc.vehicles[sc.leader].yaw), v,
                     Vec3::Zero());
    }
    if (faults.motors_off.active() && t >= faults.motors_off.time - 1e-9 &&
        !world.GetAutopilotStatus(faults.motors_off.index).motors_killed) {
      world.KillMotors(faults.motors_off.index);
      if (options.progress) {
        std::fprintf(stderr, "\n%s t = %.2f s: motors of %s off (fault)\n", options.label.c_str(),
                     t, sc.vehicles[faults.motors_off.index].name.c_str());
      }
    }
    // A vehicle downed by a fault: its first ground contact (CoM within 1.5 cm of its
    // resting height), checked every physics step for the vertical speed at contact.
    for (int i = 0; i < nv; ++i) {
      const bool downed_by_fault = killed[i] != 0 || (faults.motors_off.index == i &&
                                                      world.GetAutopilotStatus(i).motors_killed);
      if (!downed_by_fault || !std::isnan(rec.downed[i].impact_time)) continue;
      // Contact: the CoM within 1.5 cm of its resting height, or a hard or tilted impact that
      // the contact stops higher (CoM below 0.3 m above rest, about a tilted foot's reach, and
      // an upward jump of the vertical speed of more than 0.02 m/s in one 1 ms step: > 2 g of
      // contact deceleration). The speed is the one just before the contact.
      const sim::TrueState x = world.GetTrueState(i);
      const double z = x.position.z() - sim::World::kRestHeight;
      const bool jump = x.velocity.z() - prev_vz[i] > 0.02;
      if (z < 0.015 || (z < 0.3 && jump)) {
        rec.downed[i].impact_time = t;
        rec.downed[i].impact_vz = std::min(prev_vz[i], x.velocity.z());
        rec.downed[i].impact_position = x.position;
      }
      prev_vz[i] = x.velocity.z();
    }
    while (world.PopMeasurement(&m)) {
      if (!injector.Filter(&m)) continue;  // in delivery order: its random stream is shared
      // Only the carrying vehicle's controller uses a measurement.
      if (m.vehicle >= 0 && m.vehicle < nv && ctrl[m.vehicle] && !killed[m.vehicle]) {
        if (feeder) {
          feeder->Push(m);
        } else {
          inbox[m.vehicle].push_back(m);
        }
      }
    }
    if (step % every == 0) {
      for (int i = 0; i < nv; ++i) {
        truth[i] = world.GetTrueState(i);
        positions[i] = truth[i].position;
      }
      // Separation of every pair from the truth: the closest approach of each pair, each
      // vehicle and the run, and the first time a pair came closer than a collision.
      for (int i = 0; i < nv; ++i) {
        for (int j = i + 1; j < nv; ++j) {
          const double d = (truth[i].position - truth[j].position).norm();
          PairApproach& pair = rec.pairs[PairIndex(i, j, nv)];
          if (d < pair.min_distance) {
            pair.min_distance = d;
            pair.min_time = t;
          }
          if (d < sc.metrics.collision_distance && std::isnan(pair.first_collision_time)) {
            pair.first_collision_time = t;
          }
          for (const auto& [a, b] : {std::pair{i, j}, std::pair{j, i}}) {
            VehicleRecord& A = rec.vehicles[static_cast<std::size_t>(a)];
            if (d < A.min_separation) {
              A.min_separation = d;
              A.min_separation_time = t;
              A.min_separation_to = b;
            }
          }
          if (d < rec.min_separation) {
            rec.min_separation = d;
            rec.min_separation_time = t;
            rec.min_separation_pair[0] = i;
            rec.min_separation_pair[1] = j;
          }
        }
      }
      // Leader reference and steady-state flag (formation window: trajectory start to landing).
      Vec3 ref_off, ref_v;
      trajectory.Sample(t - sc.trajectory_start, &ref_off, &ref_v);
      // Each vehicle's own window ends at its own landing (never at another one's).
      const bool settled =
          trajectory.TimeSinceStop(t - sc.trajectory_start) >= sc.metrics.settle_time;
      Vec3 leader_ref = Vec3::Constant(kNaN);
      if (manual) {
        leader_ref = sc.manual_start + ref_off;
      } else if (ctrl[sc.leader] && ctrl[sc.leader]->anchor().allFinite()) {
        leader_ref = ctrl[sc.leader]->anchor() + ref_off;
      }
      if (feeder) feeder->TakeRest([&](const Measurement& x) { inbox[x.vehicle].push_back(x); });
      // Cooperative mode: the plans that have arrived, before the control step.
      if (link) {
        link->Deliver(t, [&](int r, const formation::PlanMessage& msg) {
          if (ctrl[r] && !killed[r]) ctrl[r]->ReceivePlan(msg);
        });
      }
      // In parallel, per vehicle: its measurements, the kill fault, its control step and
      // the diagnostics (after the command in a real system; the world only gets the
      // command below, in vehicle order, so the order does not matter here).
      pool.ForEach(nv, [&](int i) {
        feed(i);
        killed_now[i] = 0;
        if (faults.kill_controller.index == i && !killed[i] &&
            t >= faults.kill_controller.time - 1e-9) {
          killed[i] = 1;  // no more Process, Control or SetCommand: the autopilot is alone
          killed_now[i] = 1;
        }
        outs[i] = formation::ControlOutput{};
        if (!killed[i] && ctrl[i]) {
          outs[i] = ctrl[i]->Control(t);
          ctrl[i]->Diagnose(&outs[i]);
          if (!options.timing) outs[i].solver_time = kNaN;
        }
      });
      if (link) {  // each plan of this step broadcast, in vehicle order (the loss draws' order)
        for (int i = 0; i < nv; ++i) {
          if (ctrl[i] && !killed[i] && ctrl[i]->MakePlan(&plan)) link->Send(plan, t);
        }
      }
      for (int i = 0; i < nv; ++i) {
        const auto& v = sc.vehicles[i];
        VehicleRecord& L = rec.vehicles[i];
        formation::ControlOutput out;
        if (killed_now[i]) {
          if (options.progress) {
            std::fprintf(stderr, "\n%s t = %.2f s: controller of %s killed (fault)\n",
                         options.label.c_str(), t, v.name.c_str());
          }
        }
        if (killed[i]) {
          out.time = t;
          if (std::isnan(L.touchdown_time) && std::isfinite(rec.downed[i].impact_time)) {
            L.touchdown_time = rec.downed[i].impact_time;
            L.touchdown_vz = rec.downed[i].impact_vz;
          }
          L.motors_off = truth[i].rotor_rpm.norm() < 1.0;
        } else if (ctrl[i]) {
          out = outs[i];
          sim::AttitudeCommand cmd;
          cmd.thrust = out.thrust;
          cmd.throttle = out.throttle;
          cmd.roll = out.roll;
          cmd.pitch = out.pitch;
          cmd.yaw = out.yaw;
          world.SetCommand(i, cmd);
          if (out.recovery == formation::RecoveryAction::kReinitialise) ++L.reinitialisations;
          if (out.recovery == formation::RecoveryAction::kShiftLandingSite) ++L.landing_site_shifts;
          if (out.recovery == formation::RecoveryAction::kLand) {
            L.tie_loss_time = t;
            L.tie_loss_reason = std::string(formation::ToString(out.recovery_reason));
            if (options.progress) {
              std::fprintf(stderr,
                           "\n%s t = %.2f s: %s lands, no formation tie to the leader (%s)\n",
                           options.label.c_str(), t, v.name.c_str(), L.tie_loss_reason.c_str());
            }
          }
          if (out.recovery == formation::RecoveryAction::kFailsafe) {
            L.failsafe_time = t;
            L.failsafe_reason = std::string(formation::ToString(out.recovery_reason));
            if (options.progress) {
              std::fprintf(stderr, "\n%s t = %.2f s: %s hands over to the failsafe (%s)\n",
                           options.label.c_str(), t, v.name.c_str(), L.failsafe_reason.c_str());
            }
          }
          if (out.nmpc) {
            if (formation::InjectedSolverFailure(ctrl[i]->config().safety, i, t,
                                                 sc.rti.sample_time))
              ++rec.injected_failures;
            ++L.steps;
            if (L.steps == 1) {
              L.first_step_time = out.solver_time;
              L.max_thrust_jump_at_switch = std::abs(out.thrust - prev[i].thrust);
            }
            if (options.timing) L.solver_time.push_back(out.solver_time);
            if (out.solver_time > sc.rti.sample_time) ++L.over_budget;
            if (out.fallback) ++L.fallbacks;
            if (out.status != rti::RtiStatus::kSuccess) ++L.failures;
            L.kkt.push_back(out.kkt);
            L.cost.push_back(out.cost);
          }
          if (out.guarded) ++L.guarded;
          if (out.attitude_offset_bounded) ++L.attitude_offset_bounded;
          if (out.nmpc && out.attitude_offset.allFinite()) L.attitude_offset = out.attitude_offset;
          if (out.neighbour_thrust_bounded > 0) {
            L.neighbour_thrust_bounded[static_cast<std::size_t>(out.neighbour_thrust_bound)] +=
                out.neighbour_thrust_bounded;
          }
          // Touchdown: the first control step of the landing phase with the true CoM within
          // 1.5 cm of its resting height (the feet touch); its true vertical speed is kept.
          const bool on_ground =
              truth[i].position.z() < sim::World::kRestHeight + kGroundContactHeight;
          if ((out.phase == FlightPhase::kLanding || out.phase == FlightPhase::kLanded ||
               out.phase == FlightPhase::kFailsafe) &&
              std::isnan(L.touchdown_time) && on_ground) {
            L.touchdown_vz = truth[i].velocity.z();
            L.touchdown_time = t;
          }
          // Ground strike: the same contact while the vehicle is meant to fly (NMPC phase,
          // or a take-off that had lifted off). Vehicles a fault downs are judged apart.
          const bool downed_by_fault =
              faults.motors_off.index == i && world.GetAutopilotStatus(i).motors_killed;
          const bool flying =
              out.phase == FlightPhase::kNmpc ||
              (out.phase == FlightPhase::kTakeoff && L.max_altitude >= kLiftOffHeight);
          if (flying && on_ground && !downed_by_fault && std::isnan(L.ground_strike_time)) {
            L.ground_strike_time = t;
            L.ground_strike_vz = std::min(L.previous_vz, truth[i].velocity.z());
            L.ground_strike_phase = std::string(formation::ToString(out.phase));
            if (options.progress) {
              std::fprintf(stderr, "\n%s t = %.2f s: %s struck the ground (%s phase)\n",
                           options.label.c_str(), t, v.name.c_str(), L.ground_strike_phase.c_str());
            }
          }
          L.previous_vz = truth[i].velocity.z();
          if (out.phase == FlightPhase::kLanded) L.motors_off = true;
          // Motors off (fault): its touchdown is the impact, not what its controller sees
          // after the crash.
          if (faults.motors_off.index == i && std::isfinite(rec.downed[i].impact_time)) {
            L.touchdown_time = rec.downed[i].impact_time;
            L.touchdown_vz = rec.downed[i].impact_vz;
          }
          prev[i] = out;
        } else {
          out.phase = FlightPhase::kNmpc;
          out.time = t;
        }
        outs[i] = out;
      }
      // In parallel, per vehicle: its flight envelope, formation errors and CSV row (each
      // task writes only its vehicle's record and CSV file).
      pool.ForEach(nv, [&](int i) {
        const auto& v = sc.vehicles[i];
        VehicleRecord& L = rec.vehicles[i];
        const bool window = t >= sc.trajectory_start && t < config::LandingTime(sc, i);
        const bool steady = window && settled;
        const formation::ControlOutput& out = outs[i];
        const sim::TrueState& x = truth[i];
        // Flight envelope (from the truth): altitude above the ground and horizontal distance
        // from the start; the first excursion is kept.
        {
          const double altitude = x.position.z() - sim::World::kRestHeight;
          const Vec3 start = world_config.vehicles[static_cast<std::size_t>(i)].position;
          const double distance = (x.position - start).head<2>().norm();
          L.max_altitude = std::max(L.max_altitude, altitude);
          L.max_distance = std::max(L.max_distance, distance);
          if (std::isnan(L.envelope_time) && (!(altitude <= sc.envelope.max_altitude) ||
                                              !(distance <= sc.envelope.max_distance))) {
            L.envelope_time = t;
            L.envelope_reason = fmt::format(
                "left the flight envelope at t = {:.2f} s: altitude {:.2f} m (max_altitude "
                "{:.2f}), "
                "{:.2f} m from its start (max_distance {:.2f}), at ({:.2f}, {:.2f}, {:.2f}) m",
                t, altitude, sc.envelope.max_altitude, distance, sc.envelope.max_distance,
                x.position.x(), x.position.y(), x.position.z());
          }
        }
        // Formation errors from the truth: (p_j - p_i) in the target frame minus d_j.
        // Every neighbour's error; the CSV has columns for the first two.
        std::array<Vec3, formation::kMaxNeighbours> rel, est_rel;
        rel.fill(Vec3::Constant(kNaN));
        est_rel.fill(Vec3::Constant(kNaN));
        std::array<double, formation::kMaxNeighbours> err;
        err.fill(kNaN);
        double ferr = kNaN;
        if (!v.leader) {
          ferr = onboard::FormationError(sc, i, positions, x.euler.z(), &err, &rel);
          for (std::size_t j = 0; j < v.neighbours.size(); ++j) {
            if (ctrl[i] && j < ctrl[i]->estimates().neighbours.size()) {
              est_rel[j] = ctrl[i]->estimates().neighbours[j].head<3>();
            }
            if (window) L.nb_errors[j].push_back(err[j]);
            if (steady) L.nb_steady[j].push_back(err[j]);
          }
          if (window) L.errors.push_back(ferr);
          if (t >= sc.takeoff_time && std::isnan(L.touchdown_time)) L.flight_errors.push_back(ferr);
          if (steady) L.steady_errors.push_back(ferr);
          if (window) L.samples.push_back({t, steady, err, out.active_neighbours});
        }
        double track = kNaN;
        if (v.leader && leader_ref.allFinite()) {
          track = (x.position - leader_ref).norm();
          if (window && !manual) L.tracking.push_back(track);
        }
        const estimation::VehicleEstimate no_estimate{};
        const auto& e = ctrl[i] ? ctrl[i]->estimates().own : no_estimate;
        const std::int64_t rej = ctrl[i] ? ctrl[i]->estimator_rejections() : 0;
        VehicleLogRow row;
        row.t = t;
        row.phase = killed[i] ? std::string_view("killed") : formation::ToString(out.phase);
        row.truth = &x;
        row.estimate = &e;
        row.output = &out;
        row.leader_ref = leader_ref;
        row.tracking = v.leader ? track : kNaN;
        row.relative = &rel;
        row.estimated_relative = &est_rel;
        row.errors = &err;
        row.formation_error = ferr;
        row.steady = steady;
        row.estimator_rejections = rej;
        // m (d + the wake model's part): with compensation wake the estimator's d is the rest.
        if (ctrl[i]) {
          row.estimated_force = ctrl[i]->config().params.mass * (e.disturbance + out.wake);
        }
        csv[i].Write(row);
      });
      if (options.progress && t >= next_progress) {
        std::fprintf(stderr, "\r%s t = %5.1f / %.1f s", options.label.c_str(), t, duration);
        std::fflush(stderr);
        next_progress += 5;
      }
    }
    if (step < steps) {
      try {
        world.StepOnce();
      } catch (const sim::SimulationError& e) {
        rec.sim_error = e.what();
        break;
      }
    }
  }
  // Measurements delivered after the last control step still count in the estimators'
  // rejection totals.
  if (feeder) feeder->TakeRest([&](const Measurement& x) { inbox[x.vehicle].push_back(x); });
  pool.ForEach(nv, feed);
  if (options.progress)
    std::fprintf(stderr, "\r%s t = %5.1f / %.1f s\n", options.label.c_str(), duration, duration);
  for (VehicleCsvLog& log : csv) log.Finish();
  for (int i = 0; i < nv; ++i) {
    rec.controlled.push_back(ctrl[i] ? 1 : 0);
    rec.estimator_rejections.push_back(ctrl[i] ? ctrl[i]->estimator_rejections() : 0);
    if (ctrl[i]) rec.vehicles[i].neighbour_departures = ctrl[i]->neighbour_departures();
    rec.final_state.push_back(world.GetTrueState(i));
    rec.final_autopilot.push_back(world.GetAutopilotStatus(i));
  }
  for (std::size_t w = 0; w < faults.sensor_dropouts.size(); ++w)
    rec.dropped.push_back(injector.dropped(w));
  rec.measurements = injector.measurements();
  rec.outliers = injector.outliers();
  if (link) {
    rec.link = true;
    rec.link_stats = link->statistics();
  }
  return rec;
}

}  // namespace fnmpc::experiment

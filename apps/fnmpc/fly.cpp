// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc fly VEHICLE SCENARIO --link ... --autopilot px4|ardupilot`: the onboard executable.
// Flies one vehicle of a scenario through its flight controller over MAVLink (docs/autopilot.md):
// measurements from the link into the vehicle's estimators, the controller's attitude and
// normalised thrust out as SET_ATTITUDE_TARGET, the PX4 offboard / ArduPilot GUIDED_NOGPS
// handshake and the watchdogs of autopilot::AutopilotSession.
#include <fmt/core.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/onboard/controller_setup.hpp"
#include "fnmpc/onboard/onboard_link.hpp"

namespace fnmpc::app {
namespace {

struct FlyArgs {
  std::string vehicle;
  std::string scenario;
  std::string link;
  std::string autopilot;
  std::string link_settings;
  std::string signing_key;
  std::string clock = "local";
  std::string out;
  long long seed = -1;
  double lockstep_timeout = 10.0;
  bool quiet = false;
};

int VehicleIndex(const config::ScenarioConfig& sc, const std::string& name) {
  std::string names;
  for (std::size_t i = 0; i < sc.vehicles.size(); ++i) {
    if (sc.vehicles[i].name == name) return static_cast<int>(i);
    names += (i ? ", " : "") + sc.vehicles[i].name;
  }
  throw std::invalid_argument("vehicle '" + name + "' is not in scenario " + sc.name +
                              " (vehicles: " + names + ")");
}

/// The per-step log (one CSV row per control step) and the session's events.
class FlyLog {
 public:
  FlyLog(const std::string& dir, const std::string& vehicle, bool quiet)
      : label_("[fly " + vehicle + "]"), quiet_(quiet) {
    csv_ = std::fopen(config::PathInside(dir, vehicle + ".csv").c_str(), "w");
    if (csv_ == nullptr) {
      throw std::runtime_error(config::PathInside(dir, vehicle + ".csv") + ": cannot write");
    }
    std::fputs(
        "t,phase,session,sent,thrust_n,normalised_thrust,roll,pitch,yaw,nmpc,solver_time_s,"
        "fallback,recovery,measurements,estimate_valid,health_flags,stale_kinds,imu_age_s,"
        "mocap_age_s\n",
        csv_);
    events_.reserve(256);
  }
  ~FlyLog() {
    if (csv_ != nullptr) std::fclose(csv_);
  }
  FlyLog(const FlyLog&) = delete;
  FlyLog& operator=(const FlyLog&) = delete;
  void Row(double t, const formation::ControlOutput& c, onboard::OnboardLink& link) {
    // The own-state estimator's health (docs/estimation.md "Health"): why an estimate is not
    // usable can be read from the log.
    const estimation::VehicleEstimate& own = link.controller().estimates().own;
    const estimation::EstimateHealth& h = own.health;
    std::fprintf(
        csv_, "%.3f,%s,%s,%d,%.4f,%.4f,%.5f,%.5f,%.5f,%d,%.6g,%d,%s,%ld,%d,%u,%u,%.4g,%.4g\n", t,
        formation::ToString(c.phase).data(), link.session_state().c_str(), link.sent() ? 1 : 0,
        c.thrust, link.normalised_thrust(), c.roll, c.pitch, c.yaw, c.nmpc ? 1 : 0, c.solver_time,
        c.fallback ? 1 : 0, formation::ToString(c.recovery).data(), link.measurements(),
        own.valid ? 1 : 0, h.flags, h.stale_kinds, h.staleness[static_cast<int>(SensorKind::kImu)],
        h.staleness[static_cast<int>(SensorKind::kMocapPose)]);
  }
  void Events(onboard::OnboardLink* link) {
    std::string line;
    nlohmann::json e;
    while (link->PopEvent(&line, &e)) {
      Say(line);
      events_.push_back(std::move(e));
    }
  }
  void Say(const std::string& what) const {
    if (!quiet_) fmt::print(stderr, "{} {}\n", label_, what);
  }
  [[nodiscard]] const std::vector<nlohmann::json>& events() const { return events_; }

 private:
  std::string label_;
  bool quiet_;
  std::FILE* csv_ = nullptr;
  std::vector<nlohmann::json> events_;
};

int Fly(const FlyArgs& a) {
  const config::ScenarioConfig sc = config::LoadScenarioFile(a.scenario);
  const int index = VehicleIndex(sc, a.vehicle);
  if (sc.leader_mode == "manual" && index == sc.leader) {
    throw std::invalid_argument("vehicle '" + a.vehicle + "' is the manually moved leader of " +
                                sc.name + ": it has no controller to fly");
  }
  const std::uint64_t seed = a.seed >= 0 ? static_cast<std::uint64_t>(a.seed) : sc.seed;
  onboard::OnboardLinkOptions options;
  options.link = a.link;
  options.autopilot = a.autopilot;
  options.settings_file = a.link_settings;
  options.autopilot_clock = a.clock == "autopilot";
  options.signing_key = a.signing_key;
  onboard::OnboardLink link(
      onboard::ControllerConfigFor(sc, index, onboard::LeaderTrajectory(sc, seed)), index, options);

  const std::string dir = a.out.empty() ? "fly-" + a.vehicle : a.out;
  std::filesystem::create_directories(dir);
  FlyLog log(dir, a.vehicle, a.quiet);
  log.Say(fmt::format("{} as system {} over {} ({}, clock {}), control every {:.3f} s", a.vehicle,
                      link.system_id(), link.describe(), a.autopilot, a.clock, sc.rti.sample_time));
  if (link.moved_takeoff()) {
    log.Say(
        fmt::format("take-off at {:.2f} s instead of the scenario's {:.2f} s: the autopilot "
                    "handshake needs handshake_time",
                    link.ready_time(), link.scenario_takeoff_time()));
  }

  StopSignalScope stop_scope;
  using Clock = std::chrono::steady_clock;
  Clock::time_point start = Clock::now();
  const auto local = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  // The mission clock (--clock local) starts when our autopilot is first heard, so the
  // warm-up and the handshake happen before the take-off whenever fly was started. Until
  // then, hello every 0.5 s (a UDP endpoint learns our address from it).
  if (!options.autopilot_clock) {
    log.Say("waiting for the autopilot");
    double last = -1.0;
    while (g_stop_signal == 0 && link.own_frames() == 0) {
      if (local() - last >= 0.5) {
        link.SayHello();
        last = local();
      }
      link.Poll(0.05, 0.0);
    }
    start = Clock::now();
    if (g_stop_signal == 0) log.Say("autopilot heard: mission clock started");
  }
  const double ts = sc.rti.sample_time;
  // Without a stop, the flight ends this long after the scenario's end (landing takes time).
  const double end = sc.duration + 30.0;
  long steps = 0, overruns = 0;
  double t = 0.0, next = 0.0, last_tick_wall = 0.0, last_hello = -1.0;
  const auto step = [&](double at) {
    const formation::ControlOutput& c = link.Step(at);
    log.Row(at, c, link);
    log.Events(&link);
    ++steps;
  };
  bool lockstep_lost = false;
  while (g_stop_signal == 0) {
    if (!options.autopilot_clock) {
      link.Poll(std::max(0.0, next - local()), local);  // stamped at receipt
      t = local();
      if (t < next) continue;
      step(t);
      next += ts;
      if (next < local()) {
        ++overruns;
        next = local() + ts;
      }
    } else {
      if (link.Poll(0.05, local())) {
        t = link.tick_time();
        step(t);
        last_tick_wall = local();
      }
      // Until the first tick the endpoint does not know our address: say hello.
      if (link.ticks() == 0 && local() - last_hello >= 0.5) {
        link.SayHello();
        last_hello = local();
      }
      if (local() - last_tick_wall > a.lockstep_timeout) {
        lockstep_lost = true;
        break;
      }
    }
    // Done: not commanding any more; in lockstep a landed vehicle answers the ticks to the end.
    if (link.stopped() &&
        (!options.autopilot_clock || !link.disarmed() || t >= sc.duration - 1e-9)) {
      break;
    }
    if (t >= end) break;
  }
  if (!link.stopped()) link.Stop(t);
  stop_scope.Restore();
  log.Events(&link);

  nlohmann::json summary = link.Summary();
  summary["vehicle"] = a.vehicle;
  summary["scenario"] = sc.name;
  summary["clock"] = a.clock;
  summary["control_steps"] = steps;
  summary["overruns"] = overruns;
  summary["events"] = log.events();
  if (lockstep_lost) {
    summary["error"] =
        fmt::format("no control tick from the autopilot for {:.1f} s", a.lockstep_timeout);
  }
  config::WriteFileAtomically(config::PathInside(dir, "fly-summary.json"), summary.dump(2) + "\n");
  log.Say(fmt::format("stopped: {}; {} steps, {} overruns; log {}", link.stop_reason(), steps,
                      overruns, dir));
  if (g_stop_signal != 0) return 128 + static_cast<int>(g_stop_signal);
  if (lockstep_lost) {
    fmt::print(stderr, "fnmpc fly: {}\n", summary["error"].get<std::string>());
    return kExitError;
  }
  return link.disarmed() ? kExitOk : kExitRunFailed;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<FlyArgs>();
  CLI::App* sub = app.add_subcommand(
      "fly", "Fly one vehicle of a scenario through its flight controller (MAVLink)");
  sub->add_option("vehicle", a->vehicle, "the vehicle's name in the scenario")->required();
  sub->add_option("scenario", a->scenario, "scenario YAML (docs/scenarios.md)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--link", a->link,
                  "udp:HOST:PORT (listen), udpout:HOST:PORT (send to) or serial:DEVICE:BAUD")
      ->required();
  sub->add_option("--autopilot", a->autopilot, "px4 (offboard) or ardupilot (GUIDED_NOGPS)")
      ->required()
      ->check(CLI::IsMember({"px4", "ardupilot"}));
  sub->add_option("--link-settings", a->link_settings,
                  "YAML file of session settings (docs/autopilot.md, 'Link settings')")
      ->check(CLI::ExistingFile);
  sub->add_option("--signing-key", a->signing_key,
                  "MAVLink 2 signing key file (64 hex digits, or 32 bytes / PX4's 40-byte key "
                  "file): sign every frame, accept only signed ones (docs/autopilot.md)")
      ->check(CLI::ExistingFile);
  sub->add_option("--clock", a->clock,
                  "local (flight: own steady clock) or autopilot (lockstep with `fnmpc "
                  "sim-link --lockstep`)")
      ->check(CLI::IsMember({"local", "autopilot"}))
      ->capture_default_str();
  sub->add_option("--lockstep-timeout", a->lockstep_timeout,
                  "[s] --clock autopilot: give up when no control tick comes this long")
      ->check(FiniteIn(0.1, 600.0))
      ->capture_default_str();
  sub->add_option("--seed", a->seed,
                  "seed of a manually moved leader's walk (default: the scenario's)");
  sub->add_option("-o,--out", a->out, "log folder (default fly-<vehicle>)");
  sub->add_flag("-q,--quiet", a->quiet, "no progress lines");
  registry.push_back({sub, [a] { return Fly(*a); }});
}

const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

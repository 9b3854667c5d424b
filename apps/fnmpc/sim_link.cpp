// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc sim-link SCENARIO --autopilot px4|ardupilot`: the simulator as a set of MAVLink flight
// controllers, one UDP port per vehicle, for `fnmpc fly` (docs/autopilot.md, "Simulator
// endpoint"). Each vehicle's sensors go out as the link's messages, its emulated PX4 or
// ArduPilot (autopilot::EmulatedAutopilot) answers modes and arming and hands the setpoint it
// flies to the simulator's attitude controller; truth-based metrics go to summary.json.
#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "fnmpc/autopilot/emulated_autopilot.hpp"
#include "fnmpc/autopilot/measurement_messages.hpp"
#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/config/settings_yaml.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/experiment/scenario_runner.hpp"
#include "fnmpc/link/link_address.hpp"
#include "fnmpc/link/mavlink_connection.hpp"
#include "fnmpc/link/signing_key.hpp"
#include "fnmpc/mavlink/frame_conversions.hpp"
#include "fnmpc/onboard/controller_setup.hpp"
#include "fnmpc/sim/world.hpp"

namespace fnmpc::app {
namespace {

using autopilot::EmulatedAutopilot;
using autopilot::FlightMode;

struct SimLinkArgs {
  std::string scenario;
  std::string autopilot;
  std::string host = "127.0.0.1";
  int port = 14600;
  bool lockstep = false;
  bool scenario_rates = false;
  bool connect = false;
  std::string bridge;
  double clock_rate = 1.0;
  std::string signing_key;
  long long seed = -1;
  std::string out;
  std::string autopilot_settings;
  double wait = 30.0;
  double reply_timeout = 5.0;
  bool quiet = false;
};

autopilot::EmulatedAutopilotSettings LoadEmulatorSettings(const std::string& path) {
  autopilot::EmulatedAutopilotSettings s;
  if (path.empty()) return s;
  config::YamlMap map = config::YamlMap::LoadFile(path);
  config::SettingsReader reader(&map);
  reader.Read(&s);
  reader.Finish();
  map.Finish();
  return s;
}

/// What the endpoint keeps of one vehicle.
struct LinkedVehicle {
  std::unique_ptr<link::MavlinkConnection> conn;
  std::unique_ptr<EmulatedAutopilot> autopilot;
  bool connected = false;
  long setpoints_armed = 0;  // SET_ATTITUDE_TARGETs received while armed
  double first_setpoint_wall = kNaN, last_setpoint_wall = kNaN;
  bool gone = false;  // stopped answering the lockstep's ticks
  bool replied = false;
  double armed_time = kNaN, airborne_time = kNaN, touchdown_time = kNaN;
  double max_altitude = 0.0;
  std::vector<double> errors, steady_errors;
  std::FILE* csv = nullptr;
};

double Mean(const std::vector<double>& v) {
  if (v.empty()) return kNaN;
  double s = 0.0;
  for (const double x : v) s += x;
  return s / static_cast<double>(v.size());
}
double Max(const std::vector<double>& v) {
  return v.empty() ? kNaN : *std::max_element(v.begin(), v.end());
}
nlohmann::json Num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

/// Traffic a real autopilot sends besides what fnmpc decodes (PX4's onboard MAVLink mode
/// streams GLOBAL_POSITION_INT, EXTENDED_SYS_STATE, ESTIMATOR_STATUS and more; MAVLink
/// common.xml gives their ids, CRC_EXTRA and payload lengths): at each control tick a
/// GLOBAL_POSITION_INT (33, 28 bytes) and an EXTENDED_SYS_STATE (245, 2 bytes: VTOL state,
/// landed state) with the truth's landed state. The onboard side must skip them by their
/// length without counting a byte as discarded (mavlink::Parser).
void SendOtherTraffic(link::MavlinkConnection& conn, const EmulatedAutopilot& ap,
                      const sim::TrueState& truth) {
  std::array<std::uint8_t, 28> global_position{};
  const auto altitude_mm = static_cast<std::int32_t>(std::lround(truth.position.z() * 1000.0));
  std::memcpy(global_position.data() + 16, &altitude_mm, sizeof altitude_mm);  // relative_alt
  conn.SendOther(33, 104, global_position);
  // MAV_LANDED_STATE: 1 on ground, 2 in air.
  const bool on_ground = !ap.armed() || truth.position.z() < sim::World::kRestHeight + 0.05;
  const std::array<std::uint8_t, 2> extended{0, static_cast<std::uint8_t>(on_ground ? 1 : 2)};
  conn.SendOther(245, 130, extended);
}

/// LOCAL_POSITION_NED of the truth: the state stream PX4's onboard mode sends at 30 Hz
/// (mavlink_main.cpp), which the onboard side does not use as a measurement but which keeps
/// its state watchdog fed like a real autopilot's telemetry.
mavlink::LocalPositionNed LocalPosition(const sim::TrueState& s, std::uint32_t time_boot_ms) {
  const Vec3 p = mavlink::EnuToNed(s.position), v = mavlink::EnuToNed(s.velocity);
  mavlink::LocalPositionNed m;
  m.time_boot_ms = time_boot_ms;
  m.x = static_cast<float>(p.x());
  m.y = static_cast<float>(p.y());
  m.z = static_cast<float>(p.z());
  m.vx = static_cast<float>(v.x());
  m.vy = static_cast<float>(v.y());
  m.vz = static_cast<float>(v.z());
  return m;
}

/// STATUSTEXT (253, CRC_EXTRA 83; severity, text[50], extensions id and chunk_seq): a message
/// for the operator, as autopilots send with refusals. Not decoded by fnmpc (an unknown id).
void SendStatusText(link::MavlinkConnection& conn, std::uint8_t severity, std::string_view text) {
  std::array<std::uint8_t, 54> payload{};
  payload[0] = severity;
  std::copy_n(text.begin(), std::min<std::size_t>(text.size(), 50), payload.begin() + 1);
  conn.SendOther(253, 83, payload);
}

int SimLink(const SimLinkArgs& a) {
  const config::ScenarioConfig sc = config::LoadScenarioFile(a.scenario);
  if (sc.leader_mode == "manual") {
    throw std::invalid_argument(sc.name +
                                ": a manually moved leader has no flight controller; "
                                "sim-link needs every vehicle flown (leader.mode: waypoints)");
  }
  const int nv = static_cast<int>(sc.vehicles.size());
  if (a.port + nv - 1 > 65535) throw std::invalid_argument("--port: the ports exceed 65535");
  const std::uint64_t seed = a.seed >= 0 ? static_cast<std::uint64_t>(a.seed) : sc.seed;
  autopilot::EmulatedAutopilotSettings es = LoadEmulatorSettings(a.autopilot_settings);
  es.autopilot = autopilot::ParseAutopilotKind(a.autopilot);

  // The world as `fnmpc run` builds it; the simulator's attitude controller lands a vehicle
  // whose setpoints stop after the emulated autopilot's own timeout.
  sim::WorldConfig wc = experiment::WorldConfigFor(sc, seed);
  wc.command_timeout.enabled = true;
  wc.command_timeout.timeout = es.setpoint_timeout;
  sim::World world(wc);
  const formation::WaypointTrajectory trajectory = onboard::LeaderTrajectory(sc, seed);

  const std::string dir = a.out.empty() ? "sim-link-" + sc.name : a.out;
  std::filesystem::create_directories(dir);
  std::vector<LinkedVehicle> v(static_cast<std::size_t>(nv));
  for (int i = 0; i < nv; ++i) {
    const std::string address =
        fmt::format("{}:{}:{}", a.connect ? "udpout" : "udp", a.host, a.port + i);
    v[i].conn = std::make_unique<link::MavlinkConnection>(
        link::OpenTransport(link::ParseLinkAddress(address)), autopilot::SystemIdOf(i),
        autopilot::mav::kCompAutopilot);
    if (!a.signing_key.empty()) v[i].conn->EnableSigning(link::ReadSigningKey(a.signing_key), 0);
    autopilot::EmulatedAutopilotSettings s = es;
    s.system_id = autopilot::SystemIdOf(i);
    v[i].autopilot = std::make_unique<EmulatedAutopilot>(s);
    const std::string csv = config::PathInside(dir, sc.vehicles[i].name + ".csv");
    v[i].csv = std::fopen(csv.c_str(), "w");
    if (v[i].csv == nullptr) throw std::runtime_error(csv + ": cannot write");
    std::fputs("t,x,y,z,yaw,armed,mode,flying,formation_error\n", v[i].csv);
    if (!a.quiet) {
      fmt::print(stderr, "[sim-link] {}: system {} on {}\n", sc.vehicles[i].name,
                 autopilot::SystemIdOf(i), v[i].conn->transport().Describe());
    }
  }
  StopSignalScope stop_scope;

  autopilot::Outbox out;
  double t = 0.0;
  int tick_ms = -1;
  const auto poll = [&](int i, double timeout) {
    v[i].conn->Poll(timeout, [&](const mavlink::Frame& f) {
      v[i].connected = true;
      v[i].autopilot->OnFrame(f, t, &out);
      if (const auto* sp = std::get_if<mavlink::SetAttitudeTarget>(&f.message)) {
        if (static_cast<int>(sp->time_boot_ms) == tick_ms) v[i].replied = true;
        // The setpoint stream the autopilot receives while armed (wall clock: real time).
        if (sp->type_mask != 0xFF && v[i].autopilot->armed()) {
          const double wall =
              std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
                  .count();
          if (v[i].setpoints_armed++ == 0) v[i].first_setpoint_wall = wall;
          v[i].last_setpoint_wall = wall;
        }
      }
    });
    for (const mavlink::Message& m : out) v[i].conn->Send(m);
    out.Clear();
  };
  using Clock = std::chrono::steady_clock;
  const auto since = [](Clock::time_point p) {
    return std::chrono::duration<double>(Clock::now() - p).count();
  };
  // Every onboard computer says hello first (our UDP side learns its address from it).
  const Clock::time_point wait_start = Clock::now();
  while (g_stop_signal == 0) {
    bool all = true;
    for (int i = 0; i < nv; ++i) {
      if (!v[i].connected) {
        poll(i, 0.01);
      }
      all = all && v[i].connected;
    }
    // --connect: the onboard computers listen; our HEARTBEATs and state stream (every
    // vehicle's, connected or not: a real autopilot's telemetry does not wait) tell them
    // where we are and keep their watchdogs fed until all are there.
    if (a.connect) {
      for (int i = 0; i < nv; ++i) {
        v[i].autopilot->Step(since(wait_start), &out);
        out.Push(LocalPosition(world.GetTrueState(i), 0));
        for (const mavlink::Message& m : out) v[i].conn->Send(m);
        out.Clear();
      }
    }
    if (all) break;
    if (since(wait_start) > a.wait) {
      std::string missing;
      for (int i = 0; i < nv; ++i) {
        if (!v[i].connected) {
          missing += fmt::format("{}{} (port {})", missing.empty() ? "" : ", ", sc.vehicles[i].name,
                                 a.port + i);
        }
      }
      throw std::runtime_error(fmt::format(
          "no onboard computer connected within {:.0f} s for: {} (start `fnmpc fly VEHICLE "
          "SCENARIO --link udpout:{}:PORT`)",
          a.wait, missing, a.host));
    }
  }
  if (!a.quiet) fmt::print(stderr, "[sim-link] all {} vehicles connected\n", nv);

  std::unique_ptr<link::Transport> bridge;
  if (!a.bridge.empty()) {
    const link::LinkAddress address = link::ParseLinkAddress(a.bridge);
    if (address.kind != link::LinkAddress::Kind::kUdpConnect) {
      throw std::invalid_argument("--bridge '" + a.bridge + "': must be udpout:HOST:PORT");
    }
    bridge = link::OpenTransport(address);
  }
  const double dt = world.physics_dt();
  const int pose_every = std::max(1, static_cast<int>(std::lround(0.005 / dt)));
  const int local_position_every = std::max(1, static_cast<int>(std::lround(1.0 / 30.0 / dt)));
  const int steps = static_cast<int>(std::lround(sc.duration / dt));
  const int every = std::max(1, static_cast<int>(std::lround(sc.rti.sample_time / dt)));
  std::vector<Vec3> positions(static_cast<std::size_t>(nv));
  std::vector<sim::TrueState> truth(static_cast<std::size_t>(nv));
  Measurement m;
  mavlink::Message msg;
  const Clock::time_point start = Clock::now();
  int next_progress = 0;
  long measurements_sent = 0;
  for (int step = 0; step <= steps && g_stop_signal == 0; ++step) {
    t = world.time();
    if (step % local_position_every == 0) {
      for (int i = 0; i < nv; ++i) {
        v[i].conn->Send(LocalPosition(world.GetTrueState(i), static_cast<std::uint32_t>(std::lround(
                                                                 t * a.clock_rate * 1000.0))));
      }
    }
    if (bridge && step % pose_every == 0) {
      // The truth for `fnmpc bridge` (its motion capture and relative sensor), 200 Hz.
      std::string poses;
      for (int i = 0; i < nv; ++i) {
        const sim::TrueState s = world.GetTrueState(i);
        poses += fmt::format("POSE {} {:.4f} {:.5f} {:.5f} {:.5f} {:.6f} {:.6f} {:.6f}\n",
                             sc.vehicles[i].name, t, s.position.x(), s.position.y(), s.position.z(),
                             s.euler.x(), s.euler.y(), s.euler.z());
      }
      bridge->Write(std::span<const std::uint8_t>(
          reinterpret_cast<const std::uint8_t*>(poses.data()), poses.size()));
    }
    while (world.PopMeasurement(&m)) {
      // With a bridge, motion capture and relative observations are its business.
      if (bridge && (m.kind == SensorKind::kMocapPose || m.kind == SensorKind::kRelative)) continue;
      m.stamp *= a.clock_rate;  // the autopilot's clock
      if (m.vehicle < 0 || m.vehicle >= nv || !autopilot::ToMessage(m, &msg)) continue;
      // The autopilot's own streams at its rates (decimated from the simulator's samples).
      if (!a.scenario_rates && !v[m.vehicle].autopilot->Streams(m.kind, m.stamp)) continue;
      v[m.vehicle].conn->Send(msg);
      ++measurements_sent;
    }
    if (step % every == 0) {
      tick_ms = static_cast<int>(std::lround(t * a.clock_rate * 1000.0));
      for (int i = 0; i < nv; ++i) {
        truth[i] = world.GetTrueState(i);
        positions[i] = truth[i].position;
        // What the autopilot's land detector sees (its estimates; here the truth).
        autopilot::LandDetectorInput motion;
        motion.vertical_speed = truth[i].velocity.z();
        motion.horizontal_speed = truth[i].velocity.head<2>().norm();
        motion.tilt_rate = truth[i].body_rates.head<2>().norm();
        motion.acceleration =
            truth[i].acceleration.allFinite() ? truth[i].acceleration.norm() : 0.0;
        v[i].autopilot->Step(t, &out, motion);
        // The control tick: the autopilot's attitude, stamped with the simulation time.
        const Eigen::Quaterniond q = mavlink::EnuFluToNedFrd(Eigen::Quaterniond(
            RotationZyx(truth[i].euler.x(), truth[i].euler.y(), truth[i].euler.z())));
        mavlink::AttitudeQuaternion att;
        att.time_boot_ms = static_cast<std::uint32_t>(tick_ms);
        att.q1 = static_cast<float>(q.w());
        att.q2 = static_cast<float>(q.x());
        att.q3 = static_cast<float>(q.y());
        att.q4 = static_cast<float>(q.z());
        const Vec3 w = mavlink::FluToFrd(truth[i].body_rates);
        att.rollspeed = static_cast<float>(w.x());
        att.pitchspeed = static_cast<float>(w.y());
        att.yawspeed = static_cast<float>(w.z());
        out.Push(att);
        for (const mavlink::Message& x : out) v[i].conn->Send(x);
        out.Clear();
        SendOtherTraffic(*v[i].conn, *v[i].autopilot, truth[i]);
        v[i].replied = false;
      }
      // Lockstep: every onboard computer answers this tick before the world moves on.
      const Clock::time_point asked = Clock::now();
      while (g_stop_signal == 0) {
        bool all = true;
        for (int i = 0; i < nv; ++i) {
          poll(i, a.lockstep ? 0.001 : 0.0);
          all = all && (v[i].replied || v[i].gone);
        }
        if (!a.lockstep || all) break;
        if (since(asked) > a.reply_timeout) {
          for (int i = 0; i < nv; ++i) {
            if (v[i].replied || v[i].gone) continue;
            v[i].gone = true;
            if (!a.quiet) {
              fmt::print(stderr, "\n[sim-link] t = {:.2f} s: {} stopped answering the ticks\n", t,
                         sc.vehicles[i].name);
            }
          }
          break;
        }
      }
      const bool settled =
          trajectory.TimeSinceStop(t - sc.trajectory_start) >= sc.metrics.settle_time;
      for (int i = 0; i < nv; ++i) {
        LinkedVehicle& L = v[i];
        EmulatedAutopilot& ap = *L.autopilot;
        const sim::AutopilotStatus status = world.GetAutopilotStatus(i);
        if (status.disarmed_by_failsafe && ap.armed()) ap.Disarm(t);  // its land detector
        const autopilot::AttitudeSetpoint sp = ap.Flying(t);
        if (sp.valid()) {
          sim::AttitudeCommand cmd;
          cmd.throttle = sp.thrust;  // normalised thrust: the collective throttle
          cmd.roll = sp.roll;
          cmd.pitch = sp.pitch;
          cmd.yaw = sp.yaw;
          world.SetCommand(i, cmd);
        }
        double ev_time = 0.0;
        const autopilot::EmulatorEvent ev = ap.TakeEvent(&ev_time);
        if (ev != autopilot::EmulatorEvent::kNone && !a.quiet) {
          fmt::print(stderr, "\n[sim-link] t = {:.2f} s: {}: {} (mode {}, {})\n", ev_time,
                     sc.vehicles[i].name, autopilot::ToString(ev), autopilot::ToString(ap.mode()),
                     ap.armed() ? "armed" : "disarmed");
        }
        if (ev == autopilot::EmulatorEvent::kDisarmRefused &&
            es.autopilot == autopilot::AutopilotKind::kPx4) {
          // Commander's message with the refusal (mavlink_log_critical: MAV_SEVERITY_CRITICAL).
          SendStatusText(*L.conn, 2, "Disarming denied: not landed");
        }
        if (ap.armed() && std::isnan(L.armed_time)) L.armed_time = t;
        const double altitude = truth[i].position.z() - sim::World::kRestHeight;
        L.max_altitude = std::max(L.max_altitude, altitude);
        if (altitude > 0.3 && std::isnan(L.airborne_time)) L.airborne_time = t;
        if (std::isfinite(L.airborne_time) && std::isnan(L.touchdown_time) && altitude < 0.015) {
          L.touchdown_time = t;
        }
        double err = kNaN;
        if (!sc.vehicles[i].leader) {
          err = onboard::FormationError(sc, i, positions, truth[i].euler.z());
          const bool window = t >= sc.trajectory_start && t < config::LandingTime(sc, i);
          if (window) L.errors.push_back(err);
          if (window && settled) L.steady_errors.push_back(err);
        }
        std::fprintf(L.csv, "%.3f,%.4f,%.4f,%.4f,%.4f,%d,%s,%d,%.5f\n", t, truth[i].position.x(),
                     truth[i].position.y(), truth[i].position.z(), truth[i].euler.z(),
                     ap.armed() ? 1 : 0, autopilot::ToString(ap.mode()).data(), sp.valid() ? 1 : 0,
                     err);
      }
      if (!a.quiet && t >= next_progress) {
        fmt::print(stderr, "\r[sim-link] t = {:5.1f} / {:.1f} s", t, sc.duration);
        next_progress += 5;
      }
    }
    if (step < steps) world.StepOnce();
    if (!a.lockstep) {  // real time: the world waits for the wall clock
      const double ahead = world.time() - since(start);
      if (ahead > 0.0) std::this_thread::sleep_for(std::chrono::duration<double>(ahead));
    }
  }
  if (!a.quiet) fmt::print(stderr, "\n");
  stop_scope.Restore();

  nlohmann::json vehicles = nlohmann::json::object();
  double mean_worst = kNaN, steady_worst = kNaN, max_worst = kNaN;
  bool all_flew = true;
  for (int i = 0; i < nv; ++i) {
    LinkedVehicle& L = v[i];
    std::fclose(L.csv);
    const mavlink::ParserCounters& pc = L.conn->counters();
    const bool landed = std::isfinite(L.touchdown_time);
    all_flew = all_flew && std::isfinite(L.armed_time) && landed && !L.gone;
    nlohmann::json j = {
        {"armed_time_s", Num(L.armed_time)},
        {"airborne_time_s", Num(L.airborne_time)},
        {"touchdown_time_s", Num(L.touchdown_time)},
        {"max_altitude_m", L.max_altitude},
        {"failsafe", L.autopilot->failsafe()},
        {"failsafe_time_s", Num(L.autopilot->failsafe_time())},
        {"final_mode", autopilot::ToString(L.autopilot->mode())},
        {"armed_at_end", L.autopilot->armed()},
        {"stopped_answering", L.gone},
        {"setpoints_armed", L.setpoints_armed},
        {"setpoint_rate_armed_hz",
         Num(L.setpoints_armed > 1 ? static_cast<double>(L.setpoints_armed - 1) /
                                         (L.last_setpoint_wall - L.first_setpoint_wall)
                                   : kNaN)},
        {"frames_in", pc.frames_ok},
        {"crc_errors", pc.crc_errors},
        {"frames_out", L.conn->frames_sent()}};
    if (!sc.vehicles[i].leader) {
      const double mean = Mean(L.errors), steady = Mean(L.steady_errors), mx = Max(L.errors);
      j["formation_error_mean_m"] = Num(mean);
      j["formation_error_steady_state_mean_m"] = Num(steady);
      j["formation_error_max_m"] = Num(mx);
      mean_worst = std::isnan(mean_worst) ? mean : std::max(mean_worst, mean);
      steady_worst = std::isnan(steady_worst) ? steady : std::max(steady_worst, steady);
      max_worst = std::isnan(max_worst) ? mx : std::max(max_worst, mx);
    }
    vehicles[sc.vehicles[i].name] = j;
  }
  const nlohmann::json summary = {{"scenario", sc.name},
                                  {"autopilot", autopilot::ToString(es.autopilot)},
                                  {"lockstep", a.lockstep},
                                  {"seed", seed},
                                  {"duration_s", sc.duration},
                                  {"complete", g_stop_signal == 0},
                                  {"wall_time_s", since(start)},
                                  {"measurements_sent", measurements_sent},
                                  {"formation_window_s", {sc.trajectory_start, sc.landing_time}},
                                  {"mean_formation_error_m", Num(mean_worst)},
                                  {"steady_state_formation_error_m", Num(steady_worst)},
                                  {"max_formation_error_m", Num(max_worst)},
                                  {"every_vehicle_armed_flew_and_landed", all_flew},
                                  {"vehicles", vehicles}};
  config::WriteFileAtomically(config::PathInside(dir, "summary.json"), summary.dump(2) + "\n");
  fmt::print("{}\n", dir);
  if (!a.quiet) {
    fmt::print(stderr,
               "[sim-link] mean formation error {:.4f} m (steady state {:.4f}, max {:.3f}); every "
               "vehicle armed, flew and landed: {}\n",
               mean_worst, steady_worst, max_worst, all_flew);
  }
  if (g_stop_signal != 0) return 128 + static_cast<int>(g_stop_signal);
  return all_flew ? kExitOk : kExitRunFailed;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<SimLinkArgs>();
  CLI::App* sub = app.add_subcommand(
      "sim-link", "Serve a scenario's vehicles as MAVLink flight controllers for `fnmpc fly`");
  sub->add_option("scenario", a->scenario, "scenario YAML (docs/scenarios.md)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--autopilot", a->autopilot, "px4 or ardupilot: whose rules to play")
      ->required()
      ->check(CLI::IsMember({"px4", "ardupilot"}));
  sub->add_option("--host", a->host, "address to listen on")->capture_default_str();
  sub->add_option("--port", a->port, "UDP port of the first vehicle; vehicle i listens on port + i")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  sub->add_flag("--lockstep", a->lockstep,
                "advance only when every `fnmpc fly --clock autopilot` answered the control "
                "tick (default: real time)");
  sub->add_flag("--connect", a->connect,
                "vehicle i sends to udpout:HOST:PORT+i (`fnmpc fly --link udp:...` listens) "
                "instead of listening there");
  sub->add_option("--bridge", a->bridge,
                  "udpout:HOST:PORT of `fnmpc bridge --poses`: send it the true poses (200 Hz) "
                  "and leave motion capture and relative observations to it");
  sub->add_flag("--scenario-rates", a->scenario_rates,
                "send IMU, compass and battery at the scenario's sensor rates instead of the "
                "emulated autopilot's stream rates (PX4: HIGHRES_IMU 50 Hz unless asked for "
                "more with MAV_CMD_SET_MESSAGE_INTERVAL)");
  sub->add_option("--clock-rate", a->clock_rate,
                  "the autopilots' clocks run this many times the simulation's (their stamps; a "
                  "lockstep PX4 runs about 2 % slow, crystals drift 50-100 ppm); real time only")
      ->check(FiniteIn(0.5, 2.0))
      ->excludes("--lockstep")
      ->capture_default_str();
  sub->add_option("--signing-key", a->signing_key,
                  "MAVLink 2 signing key file: the autopilots sign every frame and accept only "
                  "signed ones (fnmpc fly --signing-key)")
      ->check(CLI::ExistingFile);
  sub->add_option("--autopilot-settings", a->autopilot_settings,
                  "YAML file of emulated-autopilot settings (docs/autopilot.md)")
      ->check(CLI::ExistingFile);
  sub->add_option("--seed", a->seed, "noise seed (default: the scenario's)");
  sub->add_option("--wait", a->wait, "[s] wait this long for every onboard computer to connect")
      ->check(FiniteIn(0.1, 3600.0))
      ->capture_default_str();
  sub->add_option("--reply-timeout", a->reply_timeout,
                  "[s] --lockstep: a vehicle that does not answer a tick this long is dropped")
      ->check(FiniteIn(0.01, 600.0))
      ->capture_default_str();
  sub->add_option("-o,--out", a->out, "output folder (default sim-link-<scenario>)");
  sub->add_flag("-q,--quiet", a->quiet, "no progress lines");
  registry.push_back({sub, [a] { return SimLink(*a); }});
}

const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

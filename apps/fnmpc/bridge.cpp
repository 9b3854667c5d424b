// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc bridge SCENARIO --poses udp:HOST:PORT --to udpout:HOST:PORT`: the ground side of a
// formation (docs/autopilot.md, "Ground side: fnmpc bridge"). Vehicle poses come in as plain
// UDP text (a motion-capture client, or `fnmpc sim-link --bridge` with the simulator's truth);
// every vehicle gets over MAVLink its own pose (ODOMETRY, estimator MOCAP) with the scenario's
// motion-capture model and its neighbours' FNMPC_RELATIVE_OBSERVATIONs with the scenario's
// relative-sensor model (noise, rate, range, field of view), on the vehicle's system id and a
// component of the bridge's own, sent to its onboard computer (`fnmpc fly --link udp:...`).
#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "fnmpc/autopilot/measurement_messages.hpp"
#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/scenario_yaml.hpp"
#include "fnmpc/core/relative_sensor.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/link/link_address.hpp"
#include "fnmpc/link/mavlink_connection.hpp"
#include "fnmpc/link/signing_key.hpp"
#include "fnmpc/link/udp_transport.hpp"

namespace fnmpc::app {
namespace {

struct BridgeArgs {
  std::string scenario;
  std::string poses = "udp:127.0.0.1:14700";
  std::vector<std::string> to;
  int component = 197;
  long long seed = -1;
  double idle_timeout = 5.0;
  std::string signing_key;
  std::string out;
  bool quiet = false;
};

/// One vehicle's latest pose and what the bridge sends it.
struct BridgedVehicle {
  std::unique_ptr<link::MavlinkConnection> conn;
  bool has_pose = false;
  double stamp = kNaN;
  Vec3 position = Vec3::Constant(kNaN);
  Vec3 euler = Vec3::Constant(kNaN);
  double next_mocap = -kInf, next_relative = -kInf;
  long poses = 0, mocap_sent = 0, relative_sent = 0;
  std::mt19937_64 rng;
};

/// "POSE <name> <t> <x> <y> <z> <roll> <pitch> <yaw>" (ENU, ZYX Euler of the FLU body, SI):
/// the vehicle's index and pose, or an error text naming the field.
std::string ParsePoseLine(const std::string& line, const config::ScenarioConfig& sc, int* vehicle,
                          double* t, Vec3* p, Vec3* e) {
  std::istringstream in(line);
  std::string tag, name;
  in >> tag >> name;
  if (tag != "POSE") return "expected 'POSE <name> <t> <x> <y> <z> <roll> <pitch> <yaw>'";
  *vehicle = -1;
  for (std::size_t i = 0; i < sc.vehicles.size(); ++i) {
    if (sc.vehicles[i].name == name) *vehicle = static_cast<int>(i);
  }
  if (*vehicle < 0) return "vehicle '" + name + "' is not in " + sc.name;
  static constexpr std::array<const char*, 7> kFields{"t", "x", "y", "z", "roll", "pitch", "yaw"};
  std::array<double, 7> v{};
  for (std::size_t k = 0; k < v.size(); ++k) {
    std::string word;
    if (!(in >> word)) return std::string("missing field '") + kFields[k] + "'";
    char* end = nullptr;
    v[k] = std::strtod(word.c_str(), &end);
    if (end != word.c_str() + word.size() || !std::isfinite(v[k])) {
      return std::string("field '") + kFields[k] + "' is not a finite number: '" + word + "'";
    }
  }
  std::string extra;
  if (in >> extra) return "unexpected '" + extra + "' after the yaw";
  *t = v[0];
  *p = Vec3(v[1], v[2], v[3]);
  *e = Vec3(v[4], v[5], v[6]);
  return "";
}

/// Each vehicle's onboard computer: one `udpout:HOST:PORT` (vehicle i at PORT + i, the
/// vehicles on one host), or `NAME=udpout:HOST:PORT` for every vehicle (one host each).
std::vector<link::LinkAddress> VehicleAddresses(const std::vector<std::string>& to,
                                                const config::ScenarioConfig& sc) {
  const int nv = static_cast<int>(sc.vehicles.size());
  std::vector<link::LinkAddress> out(static_cast<std::size_t>(nv));
  const auto udpout = [](const std::string& text) {
    link::LinkAddress address = link::ParseLinkAddress(text);
    if (address.kind != link::LinkAddress::Kind::kUdpConnect) {
      throw std::invalid_argument("--to '" + text + "': must be udpout:HOST:PORT");
    }
    return address;
  };
  if (to.size() == 1 && to[0].find('=') == std::string::npos) {
    const link::LinkAddress first = udpout(to[0]);
    if (first.port + nv - 1 > 65535) throw std::invalid_argument("--to: the ports exceed 65535");
    for (int i = 0; i < nv; ++i) {
      out[i] = first;
      out[i].port = first.port + i;
      out[i].text = fmt::format("udpout:{}:{}", first.host, out[i].port);
    }
    return out;
  }
  std::vector<bool> given(static_cast<std::size_t>(nv), false);
  for (const std::string& entry : to) {
    const std::size_t eq = entry.find('=');
    if (eq == std::string::npos) {
      throw std::invalid_argument("--to '" + entry +
                                  "': with several addresses each is NAME=udpout:HOST:PORT");
    }
    const std::string name = entry.substr(0, eq);
    int i = -1;
    for (int k = 0; k < nv; ++k) {
      if (sc.vehicles[k].name == name) i = k;
    }
    if (i < 0) {
      throw std::invalid_argument("--to '" + entry + "': no vehicle '" + name + "' in " + sc.name);
    }
    if (given[i]) throw std::invalid_argument("--to: vehicle '" + name + "' given twice");
    out[i] = udpout(entry.substr(eq + 1));
    given[i] = true;
  }
  std::string missing;
  for (int i = 0; i < nv; ++i) {
    if (!given[i]) missing += (missing.empty() ? "" : ", ") + sc.vehicles[i].name;
  }
  if (!missing.empty()) throw std::invalid_argument("--to: no address for " + missing);
  return out;
}

/// Whether a sample of a sensor at `rate` is due at `stamp`; moves `next` on.
bool Due(double rate, double stamp, double* next) {
  if (!(rate > 0.0) || stamp < *next - 1e-9) return false;
  const double period = 1.0 / rate;
  *next = std::isinf(*next) ? stamp + period : std::max(*next + period, stamp + 0.5 * period);
  return true;
}

int Bridge(const BridgeArgs& a) {
  const config::ScenarioConfig sc = config::LoadScenarioFile(a.scenario);
  const int nv = static_cast<int>(sc.vehicles.size());
  const std::vector<link::LinkAddress> to = VehicleAddresses(a.to, sc);
  const link::LinkAddress poses = link::ParseLinkAddress(a.poses);
  if (poses.kind != link::LinkAddress::Kind::kUdpListen) {
    throw std::invalid_argument("--poses '" + a.poses + "': must be udp:HOST:PORT (listen)");
  }
  link::UdpTransport input(poses);
  const std::uint64_t seed = a.seed >= 0 ? static_cast<std::uint64_t>(a.seed) : sc.seed;
  std::vector<BridgedVehicle> v(static_cast<std::size_t>(nv));
  for (int i = 0; i < nv; ++i) {
    v[i].conn = std::make_unique<link::MavlinkConnection>(link::OpenTransport(to[i]),
                                                          autopilot::SystemIdOf(i),
                                                          static_cast<std::uint8_t>(a.component));
    if (!a.signing_key.empty()) v[i].conn->EnableSigning(link::ReadSigningKey(a.signing_key), 0);
    v[i].rng.seed(seed * 1000003ULL + static_cast<std::uint64_t>(i) + 17);
  }
  if (!a.quiet) {
    fmt::print(stderr, "[bridge] {}: poses on {}, {} vehicles as component {}\n", sc.name, a.poses,
               nv, a.component);
    for (int i = 0; i < nv; ++i) {
      fmt::print(stderr, "[bridge]   {} (system {}) -> {}\n", sc.vehicles[i].name,
                 autopilot::SystemIdOf(i), to[i].text);
    }
  }
  StopSignalScope stop_scope;
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  Clock::time_point last_pose = start;
  bool any_pose = false;
  long bad_lines = 0;
  std::string first_bad;
  std::array<std::uint8_t, 65536> buffer{};
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  double next_progress = 5.0;
  while (g_stop_signal == 0) {
    const std::size_t n = input.Read(buffer, 0.1);
    const double since_start = std::chrono::duration<double>(Clock::now() - start).count();
    if (n == 0) {
      const double idle = std::chrono::duration<double>(Clock::now() - last_pose).count();
      if (any_pose && idle > a.idle_timeout) break;
      continue;
    }
    std::istringstream lines(std::string(reinterpret_cast<const char*>(buffer.data()), n));
    std::string line;
    while (std::getline(lines, line)) {
      if (line.empty() || line[0] == '#') continue;
      int i = -1;
      double t = kNaN;
      Vec3 p, e;
      const std::string why = ParsePoseLine(line, sc, &i, &t, &p, &e);
      if (!why.empty()) {
        if (bad_lines++ == 0) first_bad = why;
        if (!a.quiet && bad_lines == 1) {
          fmt::print(stderr, "[bridge] --poses: bad line ({}): {}\n", why, line.substr(0, 120));
        }
        continue;
      }
      BridgedVehicle& b = v[i];
      b.has_pose = true;
      b.stamp = t;
      b.position = p;
      b.euler = e;
      ++b.poses;
      any_pose = true;
      last_pose = Clock::now();
    }
    // Each vehicle's sensors at their rates, from the newest poses.
    for (int i = 0; i < nv; ++i) {
      BridgedVehicle& b = v[i];
      if (!b.has_pose) continue;
      const SensorsConfig& s = sc.vehicles[i].sensors;
      const auto noise3 = [&](const Vec3& sd) {
        return Vec3(sd.x() * normal(b.rng), sd.y() * normal(b.rng), sd.z() * normal(b.rng));
      };
      if (s.mocap.enabled && Due(s.mocap.rate_hz, b.stamp, &b.next_mocap) &&
          !(uniform(b.rng) < s.mocap.dropout_probability)) {
        Measurement m;
        m.kind = SensorKind::kMocapPose;
        m.vehicle = i;
        m.stamp = b.stamp;
        m.position = b.position + noise3(s.mocap.noise);
        m.euler = b.euler + noise3(s.mocap.noise2);
        m.euler.z() = WrapAngle(m.euler.z());
        mavlink::Message msg;
        if (autopilot::ToMessage(m, &msg) && b.conn->Send(msg)) ++b.mocap_sent;
      }
      const SensorSpec& r = s.relative;
      if (!r.enabled || !Due(r.rate_hz, b.stamp, &b.next_relative)) continue;
      const Mat3 rot_wb = RotationZyx(b.euler.x(), b.euler.y(), b.euler.z());
      for (int j = 0; j < nv; ++j) {
        // The simulator's relative-sensor model (ObserveRelative, as sim::World).
        if (j == i || !v[j].has_pose || std::abs(v[j].stamp - b.stamp) > 0.05) continue;
        Measurement m;
        if (!ObserveRelative(r, rot_wb, b.position, b.euler.z(), j, v[j].position, v[j].euler.z(),
                             b.rng, uniform, normal, &m.relative)) {
          continue;
        }
        m.kind = SensorKind::kRelative;
        m.vehicle = i;
        m.stamp = b.stamp;
        mavlink::Message msg;
        if (autopilot::ToMessage(m, &msg) && b.conn->Send(msg)) ++b.relative_sent;
      }
    }
    if (!a.quiet && since_start >= next_progress) {
      long sent = 0;
      for (const BridgedVehicle& b : v) sent += b.mocap_sent + b.relative_sent;
      fmt::print(stderr, "[bridge] {:.0f} s: {} messages sent\n", since_start, sent);
      next_progress += 5.0;
    }
  }
  stop_scope.Restore();
  nlohmann::json vehicles = nlohmann::json::object();
  for (int i = 0; i < nv; ++i) {
    vehicles[sc.vehicles[i].name] = {{"poses", v[i].poses},
                                     {"mocap_sent", v[i].mocap_sent},
                                     {"relative_sent", v[i].relative_sent},
                                     {"send_failures", v[i].conn->send_failures()}};
  }
  const nlohmann::json summary = {{"scenario", sc.name},         {"seed", seed},
                                  {"component", a.component},    {"bad_lines", bad_lines},
                                  {"first_bad_line", first_bad}, {"vehicles", vehicles}};
  if (!a.out.empty()) {
    std::filesystem::create_directories(a.out);
    config::WriteFileAtomically(config::PathInside(a.out, "bridge-summary.json"),
                                summary.dump(2) + "\n");
  }
  if (!a.quiet) {
    fmt::print(stderr, "[bridge] done: {} bad pose lines{}\n", bad_lines,
               bad_lines > 0 ? " (first: " + first_bad + ")" : "");
  }
  if (g_stop_signal != 0) return 128 + static_cast<int>(g_stop_signal);
  return any_pose ? kExitOk : kExitError;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<BridgeArgs>();
  CLI::App* sub = app.add_subcommand(
      "bridge",
      "Ground side: vehicle poses in (UDP text), each vehicle's motion capture and relative "
      "observations out over MAVLink");
  sub->add_option("scenario", a->scenario, "scenario YAML: vehicles and their sensor models")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--poses", a->poses,
                  "udp:HOST:PORT to listen on for 'POSE <name> <t> <x> <y> <z> <roll> <pitch> "
                  "<yaw>' lines (ENU, rad)")
      ->capture_default_str();
  sub->add_option("--to", a->to,
                  "udpout:HOST:PORT of the first vehicle's onboard computer (vehicle i: PORT + "
                  "i), or NAME=udpout:HOST:PORT for every vehicle")
      ->required();
  sub->add_option("--component", a->component, "our MAVLink component id on every vehicle")
      ->check(CLI::Range(1, 255))
      ->capture_default_str();
  sub->add_option("--seed", a->seed, "noise seed (default: the scenario's)");
  sub->add_option("--idle-timeout", a->idle_timeout,
                  "[s] stop when no pose came this long after the first")
      ->check(FiniteIn(0.1, 3600.0))
      ->capture_default_str();
  sub->add_option("--signing-key", a->signing_key, "MAVLink 2 signing key file (as fly's)")
      ->check(CLI::ExistingFile);
  sub->add_option("-o,--out", a->out, "folder for bridge-summary.json (default: none)");
  sub->add_flag("-q,--quiet", a->quiet, "no progress lines");
  registry.push_back({sub, [a] { return Bridge(*a); }});
}

const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

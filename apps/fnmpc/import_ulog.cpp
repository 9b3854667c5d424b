// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc import-ulog LOG.ulg -o DIR`: the identification inputs of a PX4 flight log in the
// campaign formats (docs/data-formats.md): attitude_steps.csv and flight.csv, converted to
// the project's frames (world ENU, body FLU), a summary of the log (airframe, PX4 version,
// parameters, armed and in-air segments, topic rates, dropouts and timestamp gaps) printed
// and written as DIR/summary.json, and the hover thrust of the flight (docs/ulog.md).
#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "fnmpc/config/output_files.hpp"
#include "fnmpc/core/rotation.hpp"
#include "fnmpc/mavlink/frame_conversions.hpp"
#include "fnmpc/ulog/reader.hpp"
#include "fnmpc/ulog/series.hpp"

namespace fnmpc::app {

namespace fs = std::filesystem;
using ulog::TopicSeries;

namespace {

constexpr double kGravity = 9.80665;  ///< [m/s^2] standard gravity, for thrust in N

struct ImportOptions {
  std::string log;
  std::string output;
  double mass = 0.0;                ///< [kg]; 0: not given (flight.csv is not written)
  double hover_speed = 0.3;         ///< [m/s] hover: speed below this
  double hover_tilt_deg = 5.0;      ///< [deg] hover: tilt below this
  double hover_min_duration = 1.0;  ///< [s] shortest hover window
  double hover_min_height = 0.3;    ///< [m] hover: above the lowest point of the log
  double gap_factor = 5.0;          ///< a step > gap_factor x the median step is a gap
};

double Seconds(std::uint64_t us) { return static_cast<double>(us) * 1e-6; }

/// Index of the last sample at or before `t` (timestamps sorted), advancing `i` (queries in
/// increasing order); -1 before the first sample.
long HoldIndex(const std::vector<std::uint64_t>& ts, std::uint64_t t, std::size_t& i) {
  while (i < ts.size() && ts[i] <= t) ++i;
  return static_cast<long>(i) - 1;
}

/// A time interval [s] (seconds since the flight controller booted).
struct Segment {
  double start = 0.0;
  double end = 0.0;
  [[nodiscard]] double duration() const { return end - start; }
  [[nodiscard]] bool Contains(double t) const { return t >= start && t <= end; }
};

/// The runs where `predicate(value)` holds for a state topic (a value holds until the next
/// message); the last run ends at `log_end`.
template <class Pred>
std::vector<Segment> Runs(const TopicSeries& s, const std::string& column, Pred predicate,
                          double log_end) {
  std::vector<Segment> out;
  const auto& v = s.Column(column);
  bool in = false;
  for (std::size_t k = 0; k < s.size(); ++k) {
    const bool now = predicate(v[k]);
    const double t = Seconds(s.timestamp[k]);
    if (now && !in) out.push_back({t, log_end});
    if (!now && in) out.back().end = t;
    in = now;
  }
  return out;
}

/// Attitude (ENU/FLU ZYX Euler angles) from a NED/FRD quaternion (w, x, y, z).
Vec3 EulerEnuFlu(double w, double x, double y, double z) {
  Eigen::Quaterniond q(w, x, y, z);
  q.normalize();
  const Eigen::Quaterniond enu = mavlink::NedFrdToEnuFlu(q);
  return EulerZyx(enu.toRotationMatrix());
}

/// The attitude quaternion of a topic at time t: normalised linear interpolation between the
/// samples around t (the samples are at most one logging period apart).
Eigen::Quaterniond AttitudeAt(const TopicSeries& att, const std::string& prefix, std::uint64_t t,
                              std::size_t& cursor) {
  const long i = HoldIndex(att.timestamp, t, cursor);
  const auto q = [&](std::size_t k) {
    return Eigen::Quaterniond(att.Column(prefix + "[0]")[k], att.Column(prefix + "[1]")[k],
                              att.Column(prefix + "[2]")[k], att.Column(prefix + "[3]")[k]);
  };
  if (i < 0) return q(0).normalized();
  const auto k = static_cast<std::size_t>(i);
  if (k + 1 >= att.size() || att.timestamp[k] == t) return q(k).normalized();
  const double a = static_cast<double>(t - att.timestamp[k]) /
                   static_cast<double>(att.timestamp[k + 1] - att.timestamp[k]);
  Eigen::Quaterniond q0 = q(k), q1 = q(k + 1);
  if (q0.dot(q1) < 0) q1.coeffs() = -q1.coeffs();
  Eigen::Quaterniond r;
  r.coeffs() = (1 - a) * q0.coeffs() + a * q1.coeffs();
  return r.normalized();
}

double TiltOf(const Eigen::Quaterniond& q_ned_frd) {
  const Eigen::Matrix3d r = q_ned_frd.toRotationMatrix();
  return std::acos(std::clamp(r(2, 2), -1.0, 1.0));  // angle between body z and world z
}

/// Timing of one topic: rate, median step and the gaps (steps > factor x median).
nlohmann::json Timing(const TopicSeries& s, double factor, std::vector<Segment>* gaps) {
  nlohmann::json j;
  j["messages"] = s.size();
  if (s.size() < 2) return j;
  std::vector<double> steps(s.size() - 1);
  for (std::size_t k = 1; k < s.size(); ++k) {
    steps[k - 1] = Seconds(s.timestamp[k]) - Seconds(s.timestamp[k - 1]);
  }
  std::vector<double> sorted = steps;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                   sorted.end());
  const double median = sorted[sorted.size() / 2];
  const double span = Seconds(s.timestamp.back()) - Seconds(s.timestamp.front());
  j["rate_hz"] = span > 0 ? static_cast<double>(s.size() - 1) / span : 0.0;
  j["median_step_s"] = median;
  double largest = 0;
  std::size_t count = 0;
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t k = 0; k < steps.size(); ++k) {
    largest = std::max(largest, steps[k]);
    if (median > 0 && steps[k] > factor * median) {
      ++count;
      const Segment g{Seconds(s.timestamp[k]), Seconds(s.timestamp[k + 1])};
      if (gaps != nullptr) gaps->push_back(g);
      if (list.size() < 20) list.push_back({g.start, g.end});
    }
  }
  j["largest_step_s"] = largest;
  j["gaps"] = count;
  j["gap_list"] = list;  // the first 20
  return j;
}

std::string Release(double v) {
  // ver_sw_release 0xAABBCCTT: major, minor, patch, type (255 release, >= 192 rc, >= 128 beta).
  const auto r = static_cast<std::uint32_t>(v);
  const unsigned type = r & 0xFF;
  const char* kind = type == 255   ? ""
                     : type >= 192 ? " rc"
                     : type >= 128 ? " beta"
                     : type >= 64  ? " alpha"
                                   : " dev";
  return fmt::format("v{}.{}.{}{}", r >> 24, (r >> 16) & 0xFF, (r >> 8) & 0xFF, kind);
}

const TopicSeries& Need(const ulog::LogSeries& series, const ulog::Reader& reader,
                        const std::string& topic, const std::string& what) {
  const TopicSeries* s = series.Find(topic);
  if (s != nullptr) return *s;
  bool subscribed = false;
  for (const auto& sub : reader.subscriptions()) subscribed |= sub.name == topic;
  throw std::runtime_error(fmt::format(
      "{}: topic '{}' {} (needed for {}); import-ulog needs vehicle_attitude, "
      "vehicle_attitude_setpoint and vehicle_local_position",
      reader.path(), topic, subscribed ? "has no data messages" : "is not in the log", what));
}

std::string Csv(const std::vector<std::string>& header, const std::vector<std::vector<double>>& c) {
  std::string out;
  for (std::size_t k = 0; k < header.size(); ++k) out += (k ? "," : "") + header[k];
  out += "\n";
  for (std::size_t r = 0; r < c[0].size(); ++r) {
    out += fmt::format("{:.6f}", c[0][r]);  // time: microseconds as logged
    for (std::size_t k = 1; k < c.size(); ++k) out += fmt::format(",{:.9g}", c[k][r]);
    out += "\n";
  }
  return out;
}

int RunImportUlog(const ImportOptions& o) {
  ulog::Reader reader(o.log);
  const std::vector<std::string> topics{"vehicle_attitude",         "vehicle_attitude_setpoint",
                                        "vehicle_rates_setpoint",   "vehicle_local_position",
                                        "vehicle_thrust_setpoint",  "actuator_motors",
                                        "actuator_outputs",         "actuator_controls_0",
                                        "battery_status",           "sensor_combined",
                                        "vehicle_status",           "vehicle_land_detected",
                                        "vehicle_angular_velocity", "hover_thrust_estimate"};
  const ulog::LogSeries series = ulog::LogSeries::Read(reader, topics);
  const TopicSeries& att = Need(series, reader, "vehicle_attitude", "attitude_steps.csv");
  const TopicSeries& sp =
      Need(series, reader, "vehicle_attitude_setpoint", "attitude_steps.csv and flight.csv");
  const TopicSeries& pos = Need(series, reader, "vehicle_local_position", "flight.csv");

  nlohmann::json summary;
  summary["log"] = o.log;
  summary["file_size"] = reader.file_size();

  // ---- the vehicle and the software ----
  nlohmann::json vehicle;
  auto info_text = [&](const char* name) -> std::string {
    const ulog::Info* i = reader.FindInfo(name);
    if (i == nullptr) return "";
    std::string s = i->AsString();
    s.erase(std::find(s.begin(), s.end(), '\0'), s.end());
    return s;
  };
  vehicle["sys_name"] = info_text("sys_name");
  vehicle["hardware"] = info_text("ver_hw");
  vehicle["software_git"] = info_text("ver_sw");
  vehicle["software_branch"] = info_text("ver_sw_branch");
  if (const ulog::Info* rel = reader.FindInfo("ver_sw_release"); rel && rel->AsNumber()) {
    vehicle["px4_version"] = Release(*rel->AsNumber());
  }
  // The airframe: rotor geometry of the rotors in use (CA_ROTORi_* for i < CA_ROTOR_COUNT),
  // hover throttle, thrust curve, battery, and the SIH simulator's parameters when present.
  const int rotor_count = static_cast<int>(reader.ParameterValue("CA_ROTOR_COUNT").value_or(0));
  auto rotor_in_use = [&](const std::string& name) {
    if (!name.starts_with("CA_ROTOR") || name == "CA_ROTOR_COUNT") return false;
    const int i = std::atoi(name.c_str() + 8);
    return i < rotor_count;
  };
  nlohmann::json params = nlohmann::json::object();
  for (const auto& [name, p] : reader.parameters()) {
    if (name == "SYS_AUTOSTART" || name == "MPC_THR_HOVER" || name == "THR_MDL_FAC" ||
        name == "BAT1_N_CELLS" || name == "BAT_N_CELLS" || name == "SYS_HITL" ||
        name == "CA_AIRFRAME" || name == "CA_ROTOR_COUNT" || rotor_in_use(name) ||
        name.starts_with("SIH_")) {
      params[name] = p.value;
    }
  }
  vehicle["parameters"] = params;
  summary["vehicle"] = vehicle;

  // ---- segments ----
  std::uint64_t last_us = 0, first_us = std::numeric_limits<std::uint64_t>::max();
  for (const auto& sub : reader.subscriptions()) {
    if (sub.count == 0) continue;
    last_us = std::max(last_us, sub.last_timestamp);
    // Topics never published before logging started carry timestamp 0.
    if (sub.first_timestamp > 0) first_us = std::min(first_us, sub.first_timestamp);
  }
  const double log_start = Seconds(first_us), log_end = Seconds(last_us);
  std::vector<std::string> notes;
  std::vector<Segment> armed, in_air;
  if (const TopicSeries* st = series.Find("vehicle_status")) {
    armed = Runs(
        *st, "arming_state", [](double v) { return v == 2; }, log_end);  // ARMED
  } else {
    notes.push_back("no vehicle_status: armed segments unknown");
  }
  if (const TopicSeries* ld = series.Find("vehicle_land_detected")) {
    in_air = Runs(
        *ld, "landed", [](double v) { return v == 0; }, log_end);
  } else {
    notes.push_back("no vehicle_land_detected: the whole log is taken as in the air");
    in_air.push_back({log_start, log_end});
  }
  if (in_air.empty()) {
    throw std::runtime_error(o.log + ": the vehicle is never in the air (vehicle_land_detected)");
  }
  const Segment flight = *std::max_element(
      in_air.begin(), in_air.end(),
      [](const Segment& a, const Segment& b) { return a.duration() < b.duration(); });
  auto segments_json = [](const std::vector<Segment>& v) {
    nlohmann::json a = nlohmann::json::array();
    for (const Segment& s : v) a.push_back({{"start", s.start}, {"end", s.end}});
    return a;
  };
  summary["log_start_s"] = log_start;
  summary["log_end_s"] = log_end;
  summary["armed"] = segments_json(armed);
  summary["in_air"] = segments_json(in_air);
  summary["written_segment"] = {{"start", flight.start}, {"end", flight.end}};

  // ---- rates and gaps ----
  nlohmann::json timing = nlohmann::json::object();
  std::vector<Segment> gaps_in_flight;
  for (const TopicSeries& s : series.all()) {
    std::vector<Segment> gaps;
    const std::string key = s.topic + (s.multi_id ? fmt::format("[{}]", s.multi_id) : "");
    timing[key] = Timing(s, o.gap_factor, &gaps);
    if (&s == &att || &s == &sp || &s == &pos) {
      for (const Segment& g : gaps) {
        if (g.end > flight.start && g.start < flight.end) gaps_in_flight.push_back(g);
      }
    }
  }
  nlohmann::json rates = nlohmann::json::object();
  for (const auto& sub : reader.subscriptions()) {
    if (sub.count < 2) continue;
    const double span = Seconds(sub.last_timestamp) - Seconds(sub.first_timestamp);
    rates[sub.name + (sub.multi_id ? fmt::format("[{}]", sub.multi_id) : "")] =
        span > 0 ? static_cast<double>(sub.count - 1) / span : 0.0;
  }
  summary["timing"] = timing;
  summary["rates_hz"] = rates;
  nlohmann::json dropouts = nlohmann::json::array();
  double dropout_ms = 0;
  for (const auto& d : reader.dropouts()) {
    dropout_ms += d.duration_ms;
    if (dropouts.size() < 50)
      dropouts.push_back({{"at_s", Seconds(d.last_timestamp)}, {"ms", d.duration_ms}});
  }
  summary["dropouts"] = {
      {"count", reader.dropouts().size()}, {"total_ms", dropout_ms}, {"list", dropouts}};
  summary["gaps_in_written_segment"] = segments_json(gaps_in_flight);
  nlohmann::json warnings = nlohmann::json::array();
  for (const auto& w : reader.warnings())
    warnings.push_back(fmt::format("offset {}: {}", w.offset, w.what));
  summary["reader_warnings"] = warnings;
  summary["truncated"] = reader.truncated();

  // ---- commands: thrust [0, 1] from the attitude set-point ----
  const bool new_thrust = sp.Has("thrust_body[2]");
  if (!new_thrust && !sp.Has("thrust")) {
    throw std::runtime_error(o.log +
                             ": vehicle_attitude_setpoint has neither thrust_body[2] "
                             "nor thrust (needed for flight.csv)");
  }
  auto sp_thrust = [&](std::size_t k) {
    return new_thrust ? -sp.Column("thrust_body[2]")[k] : sp.Column("thrust")[k];
  };
  const bool sp_has_q = sp.Has("q_d[0]");

  // ---- attitude_steps.csv: measured attitude, references held from the set-point ----
  const std::uint64_t t0 = static_cast<std::uint64_t>(std::llround(flight.start * 1e6));
  const std::uint64_t t1 = static_cast<std::uint64_t>(std::llround(flight.end * 1e6));
  std::vector<std::vector<double>> steps(7);
  std::size_t sp_cursor = 0;
  std::uint64_t previous = 0;
  std::size_t duplicates = 0;
  for (std::size_t k = 0; k < att.size(); ++k) {
    const std::uint64_t t = att.timestamp[k];
    if (t < t0 || t > t1) continue;
    const long j = HoldIndex(sp.timestamp, t, sp_cursor);
    if (j < 0) continue;  // no reference yet
    if (t <= previous) {
      ++duplicates;
      continue;
    }
    previous = t;
    const auto js = static_cast<std::size_t>(j);
    const Vec3 ref =
        sp_has_q
            ? EulerEnuFlu(sp.Column("q_d[0]")[js], sp.Column("q_d[1]")[js], sp.Column("q_d[2]")[js],
                          sp.Column("q_d[3]")[js])
            : mavlink::EulerNedFrdToEnuFlu({sp.Column("roll_body")[js], sp.Column("pitch_body")[js],
                                            sp.Column("yaw_body")[js]});
    const Vec3 meas = EulerEnuFlu(att.Column("q[0]")[k], att.Column("q[1]")[k],
                                  att.Column("q[2]")[k], att.Column("q[3]")[k]);
    steps[0].push_back(Seconds(t));
    for (int a = 0; a < 3; ++a) {
      steps[1 + a].push_back(ref[a]);
      steps[4 + a].push_back(meas[a]);
    }
  }
  if (steps[0].size() < 10) {
    throw std::runtime_error(
        fmt::format("{}: only {} attitude samples with a reference in the "
                    "flight segment {:.2f}-{:.2f} s",
                    o.log, steps[0].size(), flight.start, flight.end));
  }

  // ---- hover: speed and tilt small, for at least hover_min_duration ----
  const TopicSeries* thrust_sp = series.Find("vehicle_thrust_setpoint");
  const TopicSeries* controls = series.Find("actuator_controls_0");
  const TopicSeries* motors = series.Find("actuator_motors");
  const TopicSeries* battery = series.Find("battery_status");
  std::string thrust_source = "vehicle_attitude_setpoint";
  if (thrust_sp != nullptr && thrust_sp->Has("xyz[2]")) {
    thrust_source = "vehicle_thrust_setpoint";
  } else if (controls != nullptr && controls->Has("control[3]")) {
    thrust_source = "actuator_controls_0";
  }
  int rotors = 0;
  if (auto n = reader.ParameterValue("CA_ROTOR_COUNT")) rotors = static_cast<int>(*n);
  std::vector<Segment> hover;
  std::vector<double> hover_u, hover_motor, hover_v;
  // Per hover window: sum of thrust, sum of voltage, thrust samples, voltage samples (so that
  // hovers at different battery voltages can be told apart).
  std::vector<std::array<double, 4>> window_sums;
  {
    std::size_t att_cursor = 0;
    std::vector<std::size_t> run;
    auto close_run = [&](std::size_t end) {
      if (run.empty()) return;
      const Segment s{Seconds(pos.timestamp[run.front()]), Seconds(pos.timestamp[run.back()])};
      if (s.duration() >= o.hover_min_duration) hover.push_back(s);
      run.clear();
      (void)end;
    };
    // Ground: the lowest point of the log (NED z is down), so that a vehicle standing still
    // on the ground between touchdown and the land detector's "landed" is no hover.
    const auto& z = pos.Column("z");
    const double ground = *std::max_element(z.begin(), z.end());
    for (std::size_t k = 0; k < pos.size(); ++k) {
      const std::uint64_t t = pos.timestamp[k];
      const double height = ground - z[k];
      const double speed =
          std::sqrt(std::pow(pos.Column("vx")[k], 2) + std::pow(pos.Column("vy")[k], 2) +
                    std::pow(pos.Column("vz")[k], 2));
      const double tilt = TiltOf(AttitudeAt(att, "q", t, att_cursor));
      bool airborne = false;
      for (const Segment& s : in_air) airborne |= s.Contains(Seconds(t));
      const bool ok = airborne && height > o.hover_min_height && speed < o.hover_speed &&
                      tilt < o.hover_tilt_deg * M_PI / 180 &&
                      (run.empty() || Seconds(t) - Seconds(pos.timestamp[run.back()]) < 0.5);
      if (!ok) close_run(k);
      if (ok) run.push_back(k);
    }
    close_run(pos.size());
  }
  // Samples of the thrust command inside the hover windows, tilt taken out: hover thrust =
  // u cos(tilt). The vertical acceleration is not: the logged az of an external-vision
  // estimate is noise of several m/s^2, and over a window of near-zero speed it averages out.
  {
    const TopicSeries& src = thrust_source == "vehicle_thrust_setpoint" ? *thrust_sp
                             : thrust_source == "actuator_controls_0"   ? *controls
                                                                        : sp;
    std::size_t att_cursor = 0, bat_cursor = 0, mot_cursor = 0;
    window_sums.assign(hover.size(), {0.0, 0.0, 0.0, 0.0});
    for (std::size_t k = 0; k < src.size(); ++k) {
      const std::uint64_t t = src.timestamp[k];
      std::size_t window = hover.size();
      for (std::size_t w = 0; w < hover.size(); ++w) {
        if (hover[w].Contains(Seconds(t))) window = w;
      }
      if (window == hover.size()) continue;
      const double u = thrust_source == "vehicle_thrust_setpoint" ? -src.Column("xyz[2]")[k]
                       : thrust_source == "actuator_controls_0"   ? src.Column("control[3]")[k]
                                                                  : sp_thrust(k);
      const double tilt = TiltOf(AttitudeAt(att, "q", t, att_cursor));
      hover_u.push_back(u * std::cos(tilt));
      window_sums[window][0] += hover_u.back();
      window_sums[window][2] += 1;
      if (battery != nullptr) {
        const long b = HoldIndex(battery->timestamp, t, bat_cursor);
        if (b >= 0) {
          hover_v.push_back(battery->Column("voltage_v")[static_cast<std::size_t>(b)]);
          window_sums[window][1] += hover_v.back();
          window_sums[window][3] += 1;
        }
      }
      if (motors != nullptr) {
        const long m = HoldIndex(motors->timestamp, t, mot_cursor);
        if (m >= 0) {
          double sum = 0;
          int n = 0;
          for (int i = 0; i < (rotors > 0 ? rotors : 12); ++i) {
            const std::string c = fmt::format("control[{}]", i);
            if (!motors->Has(c)) break;
            const double v = motors->Column(c)[static_cast<std::size_t>(m)];
            if (std::isnan(v)) break;  // unused motor outputs are NaN
            sum += v;
            ++n;
          }
          if (n > 0) hover_motor.push_back(sum / n);
        }
      }
    }
  }
  auto mean_std = [](const std::vector<double>& v) -> std::pair<double, double> {
    if (v.empty()) return {std::nan(""), std::nan("")};
    const double m = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
    double ss = 0;
    for (double x : v) ss += (x - m) * (x - m);
    return {m, v.size() > 1 ? std::sqrt(ss / static_cast<double>(v.size() - 1)) : 0.0};
  };
  const auto [u_hover, u_hover_std] = mean_std(hover_u);
  const auto [motor_hover, motor_hover_std] = mean_std(hover_motor);
  const auto [v_hover, v_hover_std] = mean_std(hover_v);
  double hover_time = 0;
  for (const Segment& s : hover) hover_time += s.duration();
  nlohmann::json hj;
  nlohmann::json windows = nlohmann::json::array();
  for (std::size_t w = 0; w < hover.size(); ++w) {
    const auto& ws = window_sums[w];
    nlohmann::json e = {{"start", hover[w].start},
                        {"end", hover[w].end},
                        {"samples", static_cast<std::size_t>(ws[2])}};
    if (ws[2] > 0) e["thrust_normalised"] = ws[0] / ws[2];
    if (ws[3] > 0) e["voltage"] = ws[1] / ws[3];
    windows.push_back(e);
  }
  hj["windows"] = windows;
  hj["duration_s"] = hover_time;
  hj["criteria"] = {{"speed_below_m_s", o.hover_speed},
                    {"height_above_m", o.hover_min_height},
                    {"tilt_below_deg", o.hover_tilt_deg},
                    {"min_duration_s", o.hover_min_duration}};
  hj["thrust_source"] = thrust_source;
  hj["samples"] = hover_u.size();
  if (!hover_u.empty()) {
    hj["thrust_normalised"] = u_hover;
    hj["thrust_normalised_std"] = u_hover_std;
    hj["thrust_normalised_std_error"] = u_hover_std / std::sqrt(double(hover_u.size()));
  }
  if (!hover_motor.empty()) {
    hj["motor_command_mean"] = motor_hover;
    hj["motor_command_std"] = motor_hover_std;
  }
  if (!hover_v.empty()) {
    hj["voltage"] = v_hover;
    hj["voltage_std"] = v_hover_std;
  }
  if (auto p = reader.ParameterValue("MPC_THR_HOVER")) hj["MPC_THR_HOVER"] = *p;
  summary["hover"] = hj;

  // ---- flight.csv: state at each local-position sample, commands held ----
  std::vector<std::vector<double>> fl(15);
  bool voltage_measured = false;
  std::string flight_note;
  if (o.mass <= 0) {
    flight_note = "flight.csv not written: its thrust_cmd is in N, give --mass";
  } else if (hover_u.empty()) {
    flight_note = "flight.csv not written: no hover window to scale the normalised thrust to N";
  } else {
    std::size_t att_cursor = 0, sp_c = 0, bat_cursor = 0;
    std::uint64_t prev = 0;
    for (std::size_t k = 0; k < pos.size(); ++k) {
      const std::uint64_t t = pos.timestamp[k];
      if (t < t0 || t > t1 || t <= prev) continue;
      const long j = HoldIndex(sp.timestamp, t, sp_c);
      if (j < 0) continue;
      prev = t;
      const auto js = static_cast<std::size_t>(j);
      const Vec3 p =
          mavlink::NedToEnu({pos.Column("x")[k], pos.Column("y")[k], pos.Column("z")[k]});
      const Vec3 v =
          mavlink::NedToEnu({pos.Column("vx")[k], pos.Column("vy")[k], pos.Column("vz")[k]});
      const Eigen::Quaterniond q = AttitudeAt(att, "q", t, att_cursor);
      const Vec3 e = EulerZyx(mavlink::NedFrdToEnuFlu(q).toRotationMatrix());
      const Vec3 ref = sp_has_q ? EulerEnuFlu(sp.Column("q_d[0]")[js], sp.Column("q_d[1]")[js],
                                              sp.Column("q_d[2]")[js], sp.Column("q_d[3]")[js])
                                : mavlink::EulerNedFrdToEnuFlu({sp.Column("roll_body")[js],
                                                                sp.Column("pitch_body")[js],
                                                                sp.Column("yaw_body")[js]});
      double volt = 0;
      if (battery != nullptr) {
        const long b = HoldIndex(battery->timestamp, t, bat_cursor);
        if (b >= 0) volt = battery->Column("voltage_v")[static_cast<std::size_t>(b)];
        if (volt > 0.5) voltage_measured = true;
      }
      const double row[15] = {Seconds(t),
                              p.x(),
                              p.y(),
                              p.z(),
                              v.x(),
                              v.y(),
                              v.z(),
                              e.x(),
                              e.y(),
                              e.z(),
                              o.mass * kGravity * sp_thrust(js) / u_hover,
                              ref.x(),
                              ref.y(),
                              ref.z(),
                              std::isfinite(volt) ? volt : 0.0};
      for (int c = 0; c < 15; ++c) fl[c].push_back(row[c]);
    }
    if (!voltage_measured) {
      // No battery monitor: the logged voltage is ADC noise near 0; write a plain 0.
      std::fill(fl[14].begin(), fl[14].end(), 0.0);
      notes.push_back("no battery voltage in the log (below 0.5 V): flight.csv voltage is 0");
    }
  }

  // ---- write ----
  fs::create_directories(o.output);
  const std::string steps_path = config::PathInside(o.output, "attitude_steps.csv");
  config::WriteFileAtomically(
      steps_path, Csv({"t", "roll_ref", "pitch_ref", "yaw_ref", "roll", "pitch", "yaw"}, steps));
  nlohmann::json files = {{"attitude_steps", "attitude_steps.csv"}};
  if (!fl[0].empty()) {
    config::WriteFileAtomically(config::PathInside(o.output, "flight.csv"),
                                Csv({"t", "x", "y", "z", "vx", "vy", "vz", "roll", "pitch", "yaw",
                                     "thrust_cmd", "roll_cmd", "pitch_cmd", "yaw_cmd", "voltage"},
                                    fl));
    files["flight"] = "flight.csv";
    summary["flight_rows"] = fl[0].size();
    summary["thrust_cmd_scale_N"] = o.mass * kGravity / u_hover;
  } else {
    notes.push_back(flight_note);
  }
  summary["files"] = files;
  summary["attitude_rows"] = steps[0].size();
  summary["attitude_duplicate_timestamps_dropped"] = duplicates;
  summary["frames"] =
      "world ENU (x east, y north, z up), body FLU; angles ZYX roll, pitch, yaw [rad]; t [s] "
      "since the flight controller booted";
  summary["notes"] = notes;
  config::WriteFileAtomically(config::PathInside(o.output, "summary.json"), summary.dump(2) + "\n");

  // ---- print ----
  fmt::print(
      "{}: PX4 {} ({}), {} {}, SYS_AUTOSTART {}\n", o.log,
      vehicle.value("px4_version", std::string("?")), vehicle["software_branch"].get<std::string>(),
      vehicle["sys_name"].get<std::string>(), vehicle["hardware"].get<std::string>(),
      params.contains("SYS_AUTOSTART") ? fmt::format("{}", params["SYS_AUTOSTART"].get<double>())
                                       : "?");
  std::string shown;
  for (const auto& [k, v] : params.items()) {
    // The line shows the geometry (position, moment ratio); the JSON has every value.
    if (k.starts_with("SIH_") ||
        (k.starts_with("CA_ROTOR") && k != "CA_ROTOR_COUNT" && !k.ends_with("_PX") &&
         !k.ends_with("_PY") && !k.ends_with("_KM"))) {
      continue;
    }
    shown += fmt::format(" {}={:g}", k, v.get<double>());
  }
  fmt::print("  parameters:{}\n", shown);
  fmt::print(
      "  log {:.2f}-{:.2f} s ({:.1f} s), {} subscriptions, {} dropouts ({:.0f} ms), {} reader "
      "warnings{}\n",
      log_start, log_end, log_end - log_start, reader.subscriptions().size(),
      reader.dropouts().size(), dropout_ms, reader.warnings().size(),
      reader.truncated() ? ", TRUNCATED" : "");
  for (const auto& w : reader.warnings())
    fmt::print("  warning: offset {}: {}\n", w.offset, w.what);
  auto print_segments = [](const char* name, const std::vector<Segment>& v) {
    std::string s;
    for (const Segment& g : v) s += fmt::format(" {:.2f}-{:.2f}", g.start, g.end);
    fmt::print("  {}:{}\n", name, s.empty() ? " none" : s);
  };
  print_segments("armed", armed);
  print_segments("in air", in_air);
  std::string rate_line;
  for (const char* t :
       {"vehicle_attitude", "vehicle_attitude_setpoint", "vehicle_rates_setpoint",
        "vehicle_local_position", "vehicle_thrust_setpoint", "actuator_motors", "actuator_outputs",
        "actuator_controls_0", "battery_status", "sensor_combined"}) {
    if (timing.contains(t) && timing[t].contains("rate_hz")) {
      rate_line += fmt::format(" {} {:.0f} Hz ({} gaps),", t, timing[t]["rate_hz"].get<double>(),
                               timing[t]["gaps"].get<std::size_t>());
    }
  }
  if (!rate_line.empty()) rate_line.pop_back();
  fmt::print("  rates:{}\n", rate_line);
  fmt::print(
      "  gaps (> {:g}x the median step) of attitude, set-point or position in the written "
      "segment: {}\n",
      o.gap_factor, gaps_in_flight.size());
  if (!hover_u.empty()) {
    fmt::print("  hover: {} windows, {:.1f} s; thrust ({}) {:.4f} +- {:.4f}{}{}\n", hover.size(),
               hover_time, thrust_source, u_hover, u_hover_std,
               hover_motor.empty() ? "" : fmt::format("; mean motor command {:.4f}", motor_hover),
               hover_v.empty() ? "" : fmt::format(" at {:.2f} V", v_hover));
  } else {
    fmt::print("  hover: no window of {:g} s with speed < {:g} m/s and tilt < {:g} deg\n",
               o.hover_min_duration, o.hover_speed, o.hover_tilt_deg);
  }
  fmt::print("  wrote {}/attitude_steps.csv ({} rows, {:.2f}-{:.2f} s){}\n", o.output,
             steps[0].size(), flight.start, flight.end,
             fl[0].empty() ? "" : fmt::format(", flight.csv ({} rows)", fl[0].size()));
  for (const std::string& n : notes) fmt::print("  note: {}\n", n);
  fmt::print("  summary: {}/summary.json\n", o.output);
  return kExitOk;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto o = std::make_shared<ImportOptions>();
  CLI::App* sub =
      app.add_subcommand("import-ulog",
                         "Identification inputs (attitude_steps.csv, flight.csv) from a PX4 ULog "
                         "flight log, with a summary of the log (docs/ulog.md)");
  sub->add_option("log", o->log, "PX4 log (.ulg)")->required();
  sub->add_option("-o,--output", o->output, "folder to write (created if missing)")
      ->required()
      ->check(CLI::Validator(
          [](std::string& v) { return v.empty() ? std::string("must not be empty") : ""; }, "DIR",
          "NonEmpty"));
  sub->add_option("--mass", o->mass,
                  "vehicle mass [kg]: flight.csv's thrust_cmd in N = mass g u / u_hover (without "
                  "it flight.csv is not written)")
      ->check(FiniteIn(0.001, 1000.0));
  sub->add_option("--hover-speed", o->hover_speed, "hover windows: speed below [m/s]")
      ->check(FiniteIn(0.01, 10.0));
  sub->add_option("--hover-tilt", o->hover_tilt_deg, "hover windows: tilt below [deg]")
      ->check(FiniteIn(0.1, 45.0));
  sub->add_option("--hover-min-duration", o->hover_min_duration, "hover windows: shortest [s]")
      ->check(FiniteIn(0.05, 600.0));
  sub->add_option("--hover-min-height", o->hover_min_height,
                  "hover windows: height above the lowest point of the log [m]")
      ->check(FiniteIn(0.0, 1000.0));
  sub->add_option("--gap-factor", o->gap_factor,
                  "a timestamp step larger than this times the topic's median step is a gap")
      ->check(FiniteIn(1.5, 1000.0));
  registry.push_back({sub, [o] { return RunImportUlog(*o); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

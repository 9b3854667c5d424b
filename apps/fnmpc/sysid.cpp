// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc sysid CAMPAIGN.yaml -o vehicle.yaml`: identifies a vehicle file from a campaign
// (docs/data-formats.md); `fnmpc sysid synth OUTDIR`: synthesises a campaign with the
// simulator from a vehicle that differs from the shipped one (docs/sysid.md).
#include <fmt/core.h>
#include <fmt/os.h>
#include <glog/logging.h>  // Ceres logs through glog

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "apps/fnmpc/sysid_report.hpp"
#include "fnmpc/config/campaign_yaml.hpp"
#include "fnmpc/config/csv_reader.hpp"
#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/sysid/angles.hpp"
#include "fnmpc/sysid/attitude_fit.hpp"
#include "fnmpc/sysid/calibration.hpp"
#include "fnmpc/sysid/identification.hpp"
#include "fnmpc/sysid/pendulum.hpp"
#include "fnmpc/sysid/propulsion.hpp"
#if defined(FNMPC_HAVE_SIM)
#include "fnmpc/sim/world.hpp"
#endif

namespace fnmpc::app {

namespace fs = std::filesystem;

namespace {

using config::CsvTable;
namespace sid = fnmpc::sysid;

/// Variations of the synthetic campaign for the robustness study (docs/sysid.md).
struct SynthVariation {
  double delay = 0.0;                    ///< transport delay of every command [s]
  double log_rate_hz = 250.0;            ///< logging rate of the attitude steps [Hz]
  double noise_scale = 1.0;              ///< factor on every sensor noise
  double data_fraction = 1.0;            ///< share of the data (bench, swings, steps, flight)
  std::string motor_map = "polynomial";  ///< bench map: polynomial or dc (DC motor)
  bool attitude_bias = false;            ///< fly the attitude steps with the calibration bias
};

struct SysidOptions {
  std::string campaign;
  std::string output;
  bool plots = true;
  double motor_time_constant = 0.02;
  double autopilot_rate_hz = 250.0;
  double physics_dt = 0.001;
  std::string tau_convention = "auto";
  std::string synth_dir;
  unsigned seed = 7;
  bool overwrite = false;  // synth: replace an existing campaign
  SynthVariation variation;
};

// Keeps the top-level blocks `keep` of a YAML text written by SaveVehicleFile (a block is a
// line starting at column 1 and the indented lines after it).
std::string KeepTopLevelKeys(const std::string& text, const std::vector<std::string>& keep) {
  std::istringstream in(text);
  std::string line, out;
  bool on = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] != ' ' && line[0] != '#') {
      const std::string key = line.substr(0, line.find(':'));
      on = std::find(keep.begin(), keep.end(), key) != keep.end();
    }
    if (on) out += line + "\n";
  }
  return out;
}

sid::AttitudeLoopSettings LoopSettings(const SysidOptions& o) {
  sid::AttitudeLoopSettings ls;
  ls.motor_time_constant = o.motor_time_constant;
  ls.autopilot_rate_hz = o.autopilot_rate_hz;
  ls.physics_dt = o.physics_dt;
  return ls;
}

// Ceres' glog messages at fatal only while sysid runs: every outcome it logs below that (e.g.
// "E... Terminating: Residual and Jacobian evaluation failed" when a fit's start point is
// rejected, which the fits try on purpose) is also in its Solver::Summary, which the fits
// check and report; the lines said nothing the report does not (docs/sysid.md).
class QuietSolverLog {
 public:
  QuietSolverLog() : saved_(FLAGS_minloglevel) { FLAGS_minloglevel = google::GLOG_FATAL; }
  ~QuietSolverLog() { FLAGS_minloglevel = saved_; }
  QuietSolverLog(const QuietSolverLog&) = delete;
  QuietSolverLog& operator=(const QuietSolverLog&) = delete;

 private:
  int saved_;
};

int RunSysid(const SysidOptions& o) {
  if (o.output.empty()) throw std::invalid_argument("sysid: -o OUTPUT is required");
  const QuietSolverLog quiet;
  // The campaign file itself is required: every stage needs it.
  const config::Campaign c = config::LoadCampaignFile(o.campaign);
  const fs::path final_dir = sysid_report::ReportDir(o.output);
  const fs::path dir = sysid_report::MakeTemp(final_dir);

  // The campaign's data sets, each loaded here (the stage that needs one fails with the
  // reason it could not be read); the identification itself is fnmpc/sysid's.
  sid::IdentificationData data;
  data.mass = c.mass;
  data.arm_length = c.arm_length;
  data.wire_separation = c.wire_separation;
  data.wire_length = c.wire_length;
  try {
    const CsvTable csv =
        config::ReadCsv(c.propeller_bench, {"throttle", "voltage", "rpm", "thrust", "torque"});
    data.bench.data = sid::BenchData{csv.Column("throttle"), csv.Column("voltage"),
                                     csv.Column("rpm"), csv.Column("thrust"), csv.Column("torque")};
  } catch (const std::exception& e) {
    data.bench.error = e.what();
  }
  const std::array<std::string, 3> files{c.pendulum_x, c.pendulum_y, c.pendulum_z};
  for (int a = 0; a < 3; ++a) {
    try {
      const CsvTable csv = config::ReadCsv(files[a], {"t", "angle"}, "t");
      data.pendulum[a].data = sid::PendulumSwing{csv.Column("t"), csv.Column("angle")};
    } catch (const std::exception& e) {
      data.pendulum[a].error = e.what();
    }
  }
  const std::array<std::string, 3> axes{"roll", "pitch", "yaw"};
  try {
    const CsvTable csv = config::ReadCsv(
        c.attitude_steps, {"t", "roll_ref", "pitch_ref", "yaw_ref", "roll", "pitch", "yaw"}, "t");
    sid::AttitudeSteps steps;
    steps.t = csv.Column("t");
    for (int a = 0; a < 3; ++a) {
      steps.ref[a] = csv.Column(axes[a] + "_ref");
      steps.angle[a] = csv.Column(axes[a]);
    }
    data.attitude_steps.data = std::move(steps);
  } catch (const std::exception& e) {
    data.attitude_steps.error = e.what();
  }
  sid::IdentificationSettings settings;
  settings.loop = LoopSettings(o);
  settings.tau_convention = o.tau_convention;
  settings.attitude_steps_name = c.attitude_steps;
  sid::Identification id = sid::IdentifyVehicle(data, settings);
  for (const std::string& line : id.notices) fmt::print(stderr, "{}\n", line);
  for (const sid::ReportTable& table : id.tables) {
    sysid_report::WriteCsv(dir / table.file, table.header, table.columns);
  }
  model::VehicleParams& v = id.vehicle;
  nlohmann::json& j = id.summary;
  j["kind"] = "sysid";
  j["campaign"] = o.campaign;
  j["name"] = c.name;
  std::vector<std::string>& warnings = id.warnings;
  const std::vector<sysid_report::Stage>& stages = id.stages;
  const sysid_report::Stage& prop_stage = stages[0];
  const sysid_report::Stage& inertia_stage = stages[1];
  const sysid_report::Stage& att_stage = stages[2];
  const sysid_report::Stage& pd_stage = stages[3];
  const sid::PropulsionFit& prop = id.propulsion;
  const auto& fo = id.first_order;
  const auto& pd = id.pd;
  if (!c.flight.empty() && !fs::exists(c.flight)) {
    warnings.push_back(
        fmt::format("the campaign's flight file {} does not exist (sysid does not read it; fnmpc "
                    "calibrate needs it)",
                    c.flight));
  }
  for (const auto& w : warnings) fmt::print(stderr, "fnmpc: warning: sysid: {}\n", w);
  j["warnings"] = warnings;

  bool complete = true, sane = true;
  for (const auto& s : stages) {
    j["stages"].push_back(s.Json());
    complete = complete && s.ok;
    sane = sane && s.Passed();
  }
  j["complete"] = complete;
  config::WriteFileAtomically((dir / "summary.json").string(), j.dump(2) + "\n");
  sysid_report::Finalize(dir, final_dir, o.plots);

  if (complete) {
    v.Validate();
    config::SaveVehicleFile(v, o.output);
  } else {
    // Only what was identified: the file is incomplete on purpose (check-vehicle and the
    // controller reject it), so nothing unidentified passes for a result.
    const std::string tmp = o.output + ".partial.tmp";
    config::SaveVehicleFile(v, tmp);
    std::ifstream in(tmp);
    std::stringstream text;
    text << in.rdbuf();
    in.close();
    fs::remove(tmp);
    std::string failed;
    for (const auto& s : stages) {
      if (!s.ok) failed += (failed.empty() ? "" : ", ") + s.name;
    }
    std::ofstream out(o.output + ".tmp");
    out << "# INCOMPLETE vehicle file: stage(s) failed: " << failed << " (see "
        << final_dir.filename().string() << "/summary.md)\n"
        << KeepTopLevelKeys(text.str(), id.have);
    out.close();
    if (!out) throw std::runtime_error(o.output + ": write failed");
    fs::rename(o.output + ".tmp", o.output);
  }

  fmt::print("{}: identified from {}{}\n", o.output, o.campaign,
             complete ? "" : " (INCOMPLETE: see the failed stages)");
  fmt::print("  mass {:.4f} kg\n", v.mass);
  if (inertia_stage.ok) {
    fmt::print("  inertia [{:.5f}, {:.5f}, {:.5f}] kg m^2\n", v.inertia.x(), v.inertia.y(),
               v.inertia.z());
  }
  if (prop_stage.ok) {
    fmt::print("  T_k {:.4e} N/rpm^2, T_q {:.4e} N m/rpm^2, throttle rms {:.4f} (max {:.4f})\n",
               v.thrust_constant, v.torque_constant, prop.throttle_rms, prop.throttle_max_abs);
  }
  for (int a = 0; a < 3 && att_stage.ok; ++a) {
    fmt::print("  {:<5} tau {:.4f} s (first order {:.4f} s + delay {:.4f} s), k {:.4f}", axes[a],
               v.attitude_time_constant[a], fo[a].time_constant, fo[a].delay, fo[a].gain);
    if (pd_stage.ok) {
      fmt::print(", K_p {:.1f} 1/s^2, K_d {:.2f} 1/s, delay {:.3f} s", pd[a].kp, pd[a].kd,
                 pd[a].delay);
    }
    fmt::print("\n");
  }
  sysid_report::PrintStages(stages);
  fmt::print("  report: {}\n", final_dir.string());
  if (!complete) return 2;
  if (!sane) {
    for (const auto& s : stages) {
      if (s.ok && !s.Passed()) {
        fmt::print(stderr, "fnmpc: sysid: stage '{}' failed sanity check(s): {} (exit 3)\n", s.name,
                   s.FailedChecks());
      }
    }
  }
  return sane ? 0 : 3;
}

#if defined(FNMPC_HAVE_SIM)

/// The vehicle the synthetic campaign is made from: the shipped one, changed everywhere.
model::VehicleParams SynthVehicle() {
  model::VehicleParams v = config::LoadVehicleFile(std::string(FNMPC_SOURCE_DIR) +
                                                   "/config/vehicles/storm-drone-4.yaml");
  v.mass = 1.52;
  v.inertia = {0.0145, 0.0158, 0.0121};
  v.thrust_constant = 1.05e-7;
  v.torque_constant = 1.62e-9;
  // A 10 % stronger propulsion: throttle(f, V) = shipped(f / 1.1, V).
  for (int i = 0; i <= 3; ++i) v.throttle.c.row(i) /= std::pow(1.1, i);
  v.attitude_time_constant = {0.100, 0.115, 0.080};
  v.attitude_gain = {1.03, 0.98, 1.01};
  v.attitude_kp = {450.0, 420.0, 400.0};
  v.attitude_kd = v.attitude_time_constant.cwiseProduct(v.attitude_kp);
  v.arm_length = 0.24;
  v.bias = {0.020, -0.012, 0.97};
  v.has_bias = true;
  return v;
}

sim::WorldConfig SynthWorld(const model::VehicleParams& v, double z) {
  sim::WorldConfig w;
  sim::VehicleSpec s;
  s.params = v;
  s.position = Vec3(0.0, 0.0, z);
  for (SensorSpec* sp : {&s.sensors.mocap, &s.sensors.imu, &s.sensors.optical_flow,
                         &s.sensors.compass, &s.sensors.battery, &s.sensors.relative}) {
    sp->enabled = false;
  }
  s.initial_throttle = v.throttle.Throttle(v.mass * kGravity / 4.0, 16.8);
  w.vehicles = {s};
  w.ground = false;
  w.visual_geometry = false;
  return w;
}

// DC motor with winding resistance (e.g. Bangura and Mahony, "Nonlinear dynamic modeling
// for high performance control of a quadrotor", ACRA 2012): the applied voltage u V drives
// the back EMF k_e w and the winding loss R i, with i proportional to the load torque
// T_q w^2, plus a friction/dead-band term: u V = a w^2 + b w + c (w in rpm). Not a
// polynomial in (thrust, V): w = sqrt(f / T_k).
struct DcMotorMap {
  double a = 7.4e-8, b = 8.4e-4, c = 0.4;
  [[nodiscard]] double Rpm(double u, double voltage) const {
    const double rhs = u * voltage - c;
    if (!(rhs > 0.0)) return 0.0;
    return (-b + std::sqrt(b * b + 4.0 * a * rhs)) / (2.0 * a);
  }
};

int RunSynth(const SysidOptions& o) {
  const fs::path dir(o.synth_dir);
  if (o.synth_dir.empty()) throw std::invalid_argument("sysid synth: empty output directory");
  if (fs::exists(dir / "campaign.yaml") && !o.overwrite) {
    throw std::runtime_error((dir / "campaign.yaml").string() +
                             ": a campaign exists already; use --overwrite to replace it");
  }
  fs::create_directories(dir);
  const SynthVariation& var = o.variation;
  if (!(var.log_rate_hz > 0.0) || !(var.noise_scale >= 0.0) || !(var.data_fraction > 0.0) ||
      var.data_fraction > 1.0 || !(var.delay >= 0.0) ||
      (var.motor_map != "polynomial" && var.motor_map != "dc")) {
    throw std::invalid_argument(
        "sysid synth: need --log-rate > 0, --noise-scale >= 0, 0 < --data-fraction <= 1, "
        "--delay >= 0, --motor-map polynomial|dc");
  }
  const double ns = var.noise_scale, frac = var.data_fraction;
  const model::VehicleParams v = SynthVehicle();
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  // Thrust stand: throttle x voltage grid, thrust from the polynomial (or the DC motor
  // map), noisy sensors.
  {
    const DcMotorMap dc;
    std::vector<double> thr, volt, rpm, thrust, torque;
    int count = 0;
    for (double V = 14.6; V < 16.85; V += 0.2) {
      for (double u = 0.20; u < 1.001; u += 0.04) {
        // Half the data: every other grid point.
        if (frac < 1.0 && (count++ % static_cast<int>(std::lround(1.0 / frac))) != 0) continue;
        double f = 0.0, w = 0.0;
        if (var.motor_map == "dc") {
          w = dc.Rpm(u, V);
          f = v.thrust_constant * w * w;
        } else {
          f = v.throttle.Thrust(u, V);
          w = std::sqrt(std::max(f, 0.0) / v.thrust_constant);
        }
        if (!(f > 0.0)) continue;
        thr.push_back(u);
        volt.push_back(V + 0.01 * ns * normal(rng));
        rpm.push_back(w + 5.0 * ns * normal(rng));
        thrust.push_back(f * (1.0 + 0.002 * ns * normal(rng)) + 0.01 * ns * normal(rng));
        torque.push_back(v.torque_constant * w * w * (1.0 + 0.005 * ns * normal(rng)) +
                         2e-4 * ns * normal(rng));
      }
    }
    sysid_report::WriteCsv(dir / "bench.csv", {"throttle", "voltage", "rpm", "thrust", "torque"},
                           {thr, volt, rpm, thrust, torque});
    if (var.motor_map == "dc") {
      std::ofstream(dir / "truth_motor.yaml")
          << "# true throttle map of bench.csv: throttle = (a w^2 + b w + c) / V, "
             "w = sqrt(f / thrust_constant) [rpm]\n"
          << fmt::format("a: {}\nb: {}\nc: {}\nthrust_constant: {}\n", dc.a, dc.b, dc.c,
                         v.thrust_constant);
    }
  }
  // Pendulum swings: damped oscillation with the formula's period, jittered sample times,
  // white noise and a few spikes.
  const double d = 0.30, L = 1.00;
  for (int a = 0; a < 3; ++a) {
    const double period = sysid::BifilarPeriod(v.mass, d, L, v.inertia[a]);
    const double lambda = 0.04, wn = 2.0 * M_PI / period;
    const double wd = std::sqrt(wn * wn - lambda * lambda);
    std::vector<double> t, ang;
    const int samples = static_cast<int>(std::lround(3000 * frac));
    for (int k = 0; k < samples; ++k) {
      const double tk =
          0.01 * k + 0.002 * (std::uniform_real_distribution<double>(0, 1)(rng) - 0.5);
      t.push_back(tk);
      double y =
          0.25 * std::exp(-lambda * tk) * std::cos(wd * tk + 0.3 * a) + 0.002 * ns * normal(rng);
      if (k % 701 == 350) y += 0.05;  // a few outliers
      ang.push_back(y);
    }
    sysid_report::WriteCsv(dir / fmt::format("pendulum_{}.csv", "xyz"[a]), {"t", "angle"},
                           {t, ang});
  }
  // Commands reach the world after the transport delay: a queue stepped at physics_dt.
  struct Delayed {
    double due;
    sim::AttitudeCommand command;
  };
  auto advance = [&](sim::World& world, std::deque<Delayed>& queue, double duration) {
    const int steps = static_cast<int>(std::lround(duration / world.physics_dt()));
    for (int s = 0; s < steps; ++s) {
      while (!queue.empty() && queue.front().due <= world.time() + 1e-9) {
        world.SetCommand(0, queue.front().command);
        queue.pop_front();
      }
      world.StepOnce();
    }
  };
  // Attitude steps in hover (nominal vehicle; with --attitude-bias the calibration bias),
  // logged at --log-rate.
  {
    model::VehicleParams flown = v;
    if (!var.attitude_bias) {
      flown.bias = {};
      flown.has_bias = false;
    }
    sim::World world(SynthWorld(flown, 50.0));
    const double weight = v.mass * kGravity;
    world.SetCommand(0, {weight, 0.0, 0.0, 0.0});
    world.Step(0.5);
    std::deque<Delayed> queue;
    std::vector<std::vector<double>> cols(7);
    const std::array<double, 3> amp{0.10, 0.10, 0.02};
    const double t0 = world.time(), dt_log = 1.0 / var.log_rate_hz;
    // Half the data: each level held half as long (0.6 s, still > 5 time constants).
    const double hold = 1.2 * std::max(frac, 0.5);
    auto run = [&](const Vec3& ref, double duration) {
      const double thrust = weight / (std::cos(ref.x()) * std::cos(ref.y()));
      const int n = static_cast<int>(std::lround(duration / dt_log));
      for (int k = 0; k < n; ++k) {
        if (k == 0)
          queue.push_back({world.time() + var.delay, {thrust, ref.x(), ref.y(), ref.z()}});
        const sim::TrueState s = world.GetTrueState(0);
        cols[0].push_back(world.time() - t0);
        for (int i = 0; i < 3; ++i) cols[1 + i].push_back(ref[i]);
        for (int i = 0; i < 3; ++i) cols[4 + i].push_back(s.euler[i] + 0.001 * ns * normal(rng));
        advance(world, queue, dt_log);
      }
    };
    run(Vec3::Zero(), 0.4);
    for (int a = 0; a < 3; ++a) {
      for (double sgn : {1.0, 0.0, -1.0, 0.0}) {
        Vec3 ref = Vec3::Zero();
        ref[a] = sgn * amp[a];
        run(ref, hold);
      }
    }
    sysid_report::WriteCsv(dir / "attitude_steps.csv",
                           {"t", "roll_ref", "pitch_ref", "yaw_ref", "roll", "pitch", "yaw"}, cols);
  }
  // Closed-loop flight of the biased vehicle: position PD from noisy mocap at 50 Hz with
  // attitude doublets and thrust steps on top, commands and measured state logged.
  {
    sim::World world(SynthWorld(v, 50.0));
    std::deque<Delayed> queue;
    std::vector<std::vector<double>> cols(15);
    const double dt = 0.02, kp = 2.0, kd = 2.5;
    const int n = static_cast<int>(std::lround(1000 * std::max(frac, 0.5)));  // 20 s
    for (int k = 0; k < n; ++k) {
      const double t = k * dt;
      const sim::TrueState s = world.GetTrueState(0);
      Vec<9> z;
      for (int i = 0; i < 3; ++i) {
        z[i] = s.position[i] + 0.001 * ns * normal(rng);
        z[3 + i] = s.velocity[i] + 0.01 * ns * normal(rng);
        z[6 + i] = s.euler[i] + 0.002 * ns * normal(rng);
      }
      const int leg = static_cast<int>(t / (4.0 * std::max(frac, 0.5)));
      const Vec3 target = Vec3(0.0, 0.0, 50.0) +
                          Vec3(leg % 2 ? 1.0 : 0.0, leg >= 2 ? 1.0 : 0.0, leg == 3 ? 0.5 : 0.0);
      const Vec3 acc = kp * (target - z.head<3>()) - kd * z.segment<3>(3);
      const double yaw = z[8];
      const double ax = std::cos(yaw) * acc.x() + std::sin(yaw) * acc.y();
      const double ay = -std::sin(yaw) * acc.x() + std::cos(yaw) * acc.y();
      const double g = kGravity + acc.z();
      double pitch = std::atan2(ax, g), roll = std::atan2(-ay * std::cos(pitch), g);
      double thrust = v.mass * g / (std::cos(z[6]) * std::cos(z[7]));
      // Excitation: 0.06 rad doublets and +-8 % thrust steps.
      const double phase = std::fmod(t, 2.0);
      if (k > 50) {
        roll += phase < 0.3 ? 0.06 : (phase < 0.6 ? -0.06 : 0.0);
        pitch +=
            (phase >= 1.0 && phase < 1.3) ? 0.06 : ((phase >= 1.3 && phase < 1.6) ? -0.06 : 0.0);
        thrust *=
            (phase >= 0.6 && phase < 0.9) ? 1.08 : ((phase >= 1.6 && phase < 1.9) ? 0.92 : 1.0);
      }
      const double yaw_cmd = (t > 10.0 && t < 12.0) ? 0.1 : 0.0;
      queue.push_back({world.time() + var.delay, {thrust, roll, pitch, yaw_cmd}});
      cols[0].push_back(t);
      for (int i = 0; i < 9; ++i) cols[1 + i].push_back(z[i]);
      cols[10].push_back(thrust);
      cols[11].push_back(roll);
      cols[12].push_back(pitch);
      cols[13].push_back(yaw_cmd);
      cols[14].push_back(s.voltage);
      advance(world, queue, dt);
    }
    sysid_report::WriteCsv(dir / "flight.csv",
                           {"t", "x", "y", "z", "vx", "vy", "vz", "roll", "pitch", "yaw",
                            "thrust_cmd", "roll_cmd", "pitch_cmd", "yaw_cmd", "voltage"},
                           cols);
  }
  {
    std::ostringstream out;
    out << "# Synthetic campaign written by `fnmpc sysid synth` (truth: truth.yaml)\n"
        << "name: synthetic-storm-drone\n"
        << fmt::format("mass: {}\n", v.mass) << fmt::format("arm_length: {}\n", v.arm_length)
        << "propeller_bench: bench.csv\n"
        << "pendulum:\n"
        << fmt::format("  wire_separation: {}\n  wire_length: {}\n", d, L)
        << "  runs: {x: pendulum_x.csv, y: pendulum_y.csv, z: pendulum_z.csv}\n"
        << "attitude_steps: attitude_steps.csv\n"
        << "flight: flight.csv\n";
    config::WriteFileAtomically((dir / "campaign.yaml").string(), out.str());
  }
  config::SaveVehicleFile(v, (dir / "truth.yaml").string());
  fmt::print("{}: synthetic campaign (campaign.yaml, truth.yaml)\n", dir.string());
  return 0;
}
#endif

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto o = std::make_shared<SysidOptions>();
  CLI::App* sub =
      app.add_subcommand("sysid", "Identify a vehicle file from a campaign (docs/sysid.md)");
  sub->add_option("campaign", o->campaign, "campaign YAML (docs/data-formats.md)");
  sub->add_option("-o,--output", o->output, "vehicle YAML to write");
  sub->add_flag("!--no-plots", o->plots, "skip tools/sysid_report.py (CSV dumps only)");
  sub->add_option("--motor-time-constant", o->motor_time_constant,
                  "simulator motor lag for the PD fit [s]")
      ->check(FiniteIn(1e-4, 1.0));
  sub->add_option("--autopilot-rate", o->autopilot_rate_hz, "simulator autopilot rate [Hz]")
      ->check(FiniteIn(1.0, 10000.0));
  sub->add_option("--physics-dt", o->physics_dt, "simulator physics step [s]")
      ->check(FiniteIn(1e-5, 0.01));
  sub->add_option("--tau", o->tau_convention,
                  "attitude time constant: auto (the delay is a transport delay when first "
                  "order + dead time fits better than the PD loop, docs/sysid.md), lag (tau "
                  "without the fitted delay) or residence (tau + delay)")
      ->check(CLI::IsMember({"auto", "lag", "residence"}));
  sub->add_flag_callback(
      "--lag-only", [o] { o->tau_convention = "lag"; }, "same as --tau lag");
#if defined(FNMPC_HAVE_SIM)
  CLI::App* synth =
      sub->add_subcommand("synth", "Write a synthetic campaign made with the simulator");
  synth->add_option("outdir", o->synth_dir, "output directory")->required();
  synth->add_option("--seed", o->seed, "noise seed");
  synth->add_flag("--overwrite", o->overwrite, "replace an existing campaign in outdir");
  synth->add_option("--delay", o->variation.delay, "transport delay of the commands [s]")
      ->check(FiniteIn(0.0, 1.0));
  synth->add_option("--log-rate", o->variation.log_rate_hz, "attitude step logging rate [Hz]")
      ->check(FiniteIn(1.0, 10000.0));
  synth->add_option("--noise-scale", o->variation.noise_scale, "factor on every sensor noise")
      ->check(FiniteIn(0.0, 100.0));
  synth
      ->add_option("--data-fraction", o->variation.data_fraction,
                   "share of the data to record (0.5: half)")
      ->check(FiniteIn(1e-3, 1.0))
      ->check(FiniteIn(1e-3, 1.0));
  synth->add_option("--motor-map", o->variation.motor_map,
                    "bench map: polynomial (the vehicle's) or dc (DC motor with winding "
                    "resistance; truth in truth_motor.yaml)");
  synth->add_flag("--attitude-bias", o->variation.attitude_bias,
                  "fly the attitude steps with the calibration bias");
#endif
  registry.push_back({sub, [o, sub] {
#if defined(FNMPC_HAVE_SIM)
                        if (sub->got_subcommand("synth")) return RunSynth(*o);
#endif
                        if (o->campaign.empty()) {
                          throw std::invalid_argument("sysid: CAMPAIGN.yaml is required");
                        }
                        return RunSysid(*o);
                      }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc sysid CAMPAIGN.yaml -o vehicle.yaml`: identifies a vehicle file from a campaign
// (shared/data-formats.md); `fnmpc sysid synth OUTDIR`: synthesises a campaign with the
// simulator from a vehicle that differs from the shipped one (docs/sysid.md).
#include <fmt/core.h>
#include <fmt/os.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "fnmpc/config/campaign_yaml.hpp"
#include "fnmpc/config/csv_reader.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/sysid/attitude_fit.hpp"
#include "fnmpc/sysid/calibration.hpp"
#include "fnmpc/sysid/pendulum.hpp"
#include "fnmpc/sysid/propulsion.hpp"
#if defined(FNMPC_HAVE_SIM)
#include "fnmpc/sim/world.hpp"
#endif

namespace fnmpc::app {

namespace fs = std::filesystem;

/// Report helpers shared with calibrate.cpp (declared there).
namespace sysid_report {

/// Writes a CSV file with a header and rows of numbers (full precision).
void WriteCsv(const fs::path& path, const std::vector<std::string>& header,
              const std::vector<std::vector<double>>& columns) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write");
  for (std::size_t c = 0; c < header.size(); ++c) out << (c ? "," : "") << header[c];
  out << "\n";
  const std::size_t rows = columns.empty() ? 0 : columns[0].size();
  for (std::size_t r = 0; r < rows; ++r) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      out << (c ? "," : "") << fmt::format("{:.10g}", columns[c][r]);
    }
    out << "\n";
  }
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

/// The report directory of an output file: <out>.report.
fs::path ReportDir(const std::string& out) { return fs::path(out + ".report"); }

/// Runs tools/sysid_report.py on `tmp` (warning only on failure), then replaces `final_dir`
/// with `tmp` atomically (rename).
void Finalize(const fs::path& tmp, const fs::path& final_dir, bool plots) {
  if (plots) {
    const std::string script = std::string(FNMPC_SOURCE_DIR) + "/tools/sysid_report.py";
    const std::string cmd =
        "MPLBACKEND=Agg /usr/bin/python3 '" + script + "' '" + tmp.string() + "'";
    if (std::system(cmd.c_str()) != 0) {
      fmt::print(stderr, "fnmpc: warning: the report script failed ({}); CSVs are in {}\n", cmd,
                 final_dir.string());
    }
  }
  std::error_code ec;
  fs::remove_all(final_dir, ec);
  fs::rename(tmp, final_dir);
}

/// A fresh temporary directory next to `final_dir`.
fs::path MakeTemp(const fs::path& final_dir) {
  fs::path tmp = final_dir;
  tmp += ".tmp";
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp);
  return tmp;
}

}  // namespace sysid_report

namespace {

using config::CsvTable;

struct SysidOptions {
  std::string campaign;
  std::string output;
  bool plots = true;
  double motor_time_constant = 0.02;
  double autopilot_rate_hz = 250.0;
  double physics_dt = 0.001;
  bool lag_only = false;
  std::string synth_dir;
  unsigned seed = 7;
};

std::vector<double> Unwrapped(std::vector<double> a) {
  for (std::size_t i = 1; i < a.size(); ++i) {
    while (a[i] - a[i - 1] > M_PI) a[i] -= 2.0 * M_PI;
    while (a[i] - a[i - 1] < -M_PI) a[i] += 2.0 * M_PI;
  }
  return a;
}

int RunSysid(const SysidOptions& o) {
  namespace sid = fnmpc::sysid;
  if (o.output.empty()) throw std::invalid_argument("sysid: -o OUTPUT is required");
  const config::Campaign c = config::LoadCampaignFile(o.campaign);

  // Read every file first, so that a bad file fails before anything is written.
  const CsvTable bench_csv =
      config::ReadCsv(c.propeller_bench, {"throttle", "voltage", "rpm", "thrust", "torque"});
  const std::array<std::string, 3> pend_files{c.pendulum_x, c.pendulum_y, c.pendulum_z};
  std::vector<CsvTable> pend_csv;
  for (const auto& f : pend_files) pend_csv.push_back(config::ReadCsv(f, {"t", "angle"}, "t"));
  const CsvTable steps_csv = config::ReadCsv(
      c.attitude_steps, {"t", "roll_ref", "pitch_ref", "yaw_ref", "roll", "pitch", "yaw"}, "t");

  // Propulsion.
  sid::BenchData bench{bench_csv.Column("throttle"), bench_csv.Column("voltage"),
                       bench_csv.Column("rpm"), bench_csv.Column("thrust"),
                       bench_csv.Column("torque")};
  const sid::PropulsionFit prop = sid::FitPropulsion(bench);

  // Inertia.
  std::array<sid::PendulumFit, 3> pend;
  model::VehicleParams v;
  for (int a = 0; a < 3; ++a) {
    pend[a] = sid::FitPendulum(pend_csv[a].Column("t"), pend_csv[a].Column("angle"));
    v.inertia[a] =
        sid::BifilarInertia(c.mass, c.wire_separation, c.wire_length, pend[a].natural_period);
  }
  v.mass = c.mass;
  v.arm_length = c.arm_length;
  v.thrust_constant = prop.thrust_constant;
  v.torque_constant = prop.torque_constant;
  v.throttle = prop.throttle;

  // Attitude loop: first-order model, then the lumped PD gains of the simulator.
  const std::array<std::string, 3> axes{"roll", "pitch", "yaw"};
  const std::vector<double>& t = steps_csv.Column("t");
  std::array<sid::FirstOrderFit, 3> fo;
  std::array<sid::PdFit, 3> pd;
  std::array<std::vector<double>, 3> refs, angles;
  for (int a = 0; a < 3; ++a) {
    refs[a] = steps_csv.Column(axes[a] + "_ref");
    angles[a] = steps_csv.Column(axes[a]);
    if (a == 2) {
      refs[a] = Unwrapped(refs[a]);
      angles[a] = Unwrapped(angles[a]);
    }
    fo[a] = sid::FitFirstOrder(t, refs[a], angles[a]);
    sid::AttitudeLoopSettings ls;
    ls.motor_time_constant = o.motor_time_constant;
    ls.autopilot_rate_hz = o.autopilot_rate_hz;
    ls.physics_dt = o.physics_dt;
    if (a == 2) {
      // Yaw authority of the reaction torques at hover (docs/simulator.md, mixer).
      const double hover = c.mass * kGravity;
      const double fmax = prop.throttle.Thrust(1.0, 16.0);
      const double ratio = prop.torque_constant / prop.thrust_constant;
      const double room = std::isfinite(fmax) ? std::min(hover, 4.0 * fmax - hover) : hover;
      ls.max_angular_acceleration = ratio * room / v.inertia.z();
    }
    pd[a] = sid::FitPdGains(t, refs[a], angles[a], fo[a], ls);
    v.attitude_time_constant[a] = o.lag_only ? fo[a].time_constant : fo[a].equivalent_time_constant;
    v.attitude_gain[a] = fo[a].gain;
    v.attitude_kp[a] = pd[a].kp;
    v.attitude_kd[a] = pd[a].kd;
  }
  v.Validate();

  // Report: CSV dumps + summary.json, plots and summary.md by tools/sysid_report.py.
  const fs::path final_dir = sysid_report::ReportDir(o.output);
  const fs::path dir = sysid_report::MakeTemp(final_dir);
  {
    std::vector<double> fit_thr, fit_thrust, fit_torque;
    for (std::size_t i = 0; i < bench.throttle.size(); ++i) {
      fit_thr.push_back(prop.throttle.Throttle(bench.thrust[i], bench.voltage[i]));
      fit_thrust.push_back(prop.thrust_constant * bench.rpm[i] * bench.rpm[i]);
      fit_torque.push_back(prop.torque_constant * bench.rpm[i] * bench.rpm[i]);
    }
    sysid_report::WriteCsv(dir / "bench.csv",
                           {"throttle", "voltage", "rpm", "thrust", "torque", "throttle_fit",
                            "thrust_fit", "torque_fit"},
                           {bench.throttle, bench.voltage, bench.rpm, bench.thrust, bench.torque,
                            fit_thr, fit_thrust, fit_torque});
    for (int a = 0; a < 3; ++a) {
      const auto& pt = pend_csv[a].Column("t");
      std::vector<double> fit;
      for (double ti : pt) fit.push_back(pend[a].Evaluate(ti));
      sysid_report::WriteCsv(dir / fmt::format("pendulum_{}.csv", "xyz"[a]), {"t", "angle", "fit"},
                             {pt, pend_csv[a].Column("angle"), fit});
      std::vector<double> y1, y2;
      sid::SimulateFirstOrder<double>(t, refs[a], fo[a].time_constant, fo[a].gain, fo[a].delay,
                                      fo[a].initial, &y1);
      sid::AttitudeLoopSettings ls;
      ls.motor_time_constant = o.motor_time_constant;
      ls.autopilot_rate_hz = o.autopilot_rate_hz;
      ls.physics_dt = o.physics_dt;
      sid::SimulateAttitudeLoop<double>(t, refs[a], fo[a].gain, pd[a].kp, pd[a].kd, fo[a].initial,
                                        ls, &y2);
      sysid_report::WriteCsv(dir / fmt::format("attitude_{}.csv", axes[a]),
                             {"t", "ref", "angle", "first_order", "pd_loop"},
                             {t, refs[a], angles[a], y1, y2});
    }
    nlohmann::json j;
    j["kind"] = "sysid";
    j["campaign"] = o.campaign;
    j["name"] = c.name;
    j["mass"] = v.mass;
    j["thrust_constant"] = prop.thrust_constant;
    j["torque_constant"] = prop.torque_constant;
    j["thrust_rms"] = prop.thrust_rms;
    j["torque_rms"] = prop.torque_rms;
    j["throttle_rms"] = prop.throttle_rms;
    j["throttle_max_abs"] = prop.throttle_max_abs;
    j["bench_samples"] = prop.samples;
    for (int a = 0; a < 3; ++a) {
      const std::string ax(1, "xyz"[a]);
      j["pendulum"][ax] = {{"natural_period", pend[a].natural_period},
                           {"damped_period", pend[a].damped_period},
                           {"decay_rate", pend[a].decay_rate},
                           {"rms", pend[a].rms},
                           {"inertia", v.inertia[a]}};
      j["attitude"][axes[a]] = {{"time_constant", fo[a].time_constant},
                                {"delay", fo[a].delay},
                                {"equivalent_time_constant", fo[a].equivalent_time_constant},
                                {"gain", fo[a].gain},
                                {"rms", fo[a].rms},
                                {"kp", pd[a].kp},
                                {"kd", pd[a].kd},
                                {"pd_rms", pd[a].rms},
                                {"pd_rms_to_first_order", pd[a].rms_to_first_order}};
    }
    std::ofstream(dir / "summary.json") << j.dump(2) << "\n";
  }
  sysid_report::Finalize(dir, final_dir, o.plots);
  config::SaveVehicleFile(v, o.output);

  fmt::print("{}: identified from {}\n", o.output, o.campaign);
  fmt::print("  mass {:.4f} kg, inertia [{:.5f}, {:.5f}, {:.5f}] kg m^2\n", v.mass, v.inertia.x(),
             v.inertia.y(), v.inertia.z());
  fmt::print("  T_k {:.4e} N/rpm^2, T_q {:.4e} N m/rpm^2, throttle rms {:.4f} (max {:.4f})\n",
             v.thrust_constant, v.torque_constant, prop.throttle_rms, prop.throttle_max_abs);
  for (int a = 0; a < 3; ++a) {
    fmt::print(
        "  {:<5} tau {:.4f} s (first order {:.4f} s + delay {:.4f} s), k {:.4f}, "
        "K_p {:.1f} 1/s^2, K_d {:.2f} 1/s\n",
        axes[a], fo[a].equivalent_time_constant, fo[a].time_constant, fo[a].delay, fo[a].gain,
        pd[a].kp, pd[a].kd);
  }
  fmt::print("  report: {}\n", final_dir.string());
  return 0;
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

int RunSynth(const SysidOptions& o) {
  const fs::path dir(o.synth_dir);
  fs::create_directories(dir);
  const model::VehicleParams v = SynthVehicle();
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  // Thrust stand: throttle x voltage grid, thrust from the polynomial, noisy sensors.
  {
    std::vector<double> thr, volt, rpm, thrust, torque;
    for (double V = 14.6; V < 16.85; V += 0.2) {
      for (double u = 0.20; u < 1.001; u += 0.04) {
        const double f = v.throttle.Thrust(u, V);
        if (!(f > 0.0)) continue;
        const double w = std::sqrt(f / v.thrust_constant);
        thr.push_back(u);
        volt.push_back(V + 0.01 * normal(rng));
        rpm.push_back(w + 5.0 * normal(rng));
        thrust.push_back(f * (1.0 + 0.002 * normal(rng)) + 0.01 * normal(rng));
        torque.push_back(v.torque_constant * w * w * (1.0 + 0.005 * normal(rng)) +
                         2e-4 * normal(rng));
      }
    }
    sysid_report::WriteCsv(dir / "bench.csv", {"throttle", "voltage", "rpm", "thrust", "torque"},
                           {thr, volt, rpm, thrust, torque});
  }
  // Pendulum swings: damped oscillation with the formula's period, jittered sample times,
  // white noise and a few spikes.
  const double d = 0.30, L = 1.00;
  for (int a = 0; a < 3; ++a) {
    const double period = sysid::BifilarPeriod(v.mass, d, L, v.inertia[a]);
    const double lambda = 0.04, wn = 2.0 * M_PI / period;
    const double wd = std::sqrt(wn * wn - lambda * lambda);
    std::vector<double> t, ang;
    for (int k = 0; k < 3000; ++k) {
      const double tk =
          0.01 * k + 0.002 * (std::uniform_real_distribution<double>(0, 1)(rng) - 0.5);
      t.push_back(tk);
      double y = 0.25 * std::exp(-lambda * tk) * std::cos(wd * tk + 0.3 * a) + 0.002 * normal(rng);
      if (k % 701 == 350) y += 0.05;  // a few outliers
      ang.push_back(y);
    }
    sysid_report::WriteCsv(dir / fmt::format("pendulum_{}.csv", "xyz"[a]), {"t", "angle"},
                           {t, ang});
  }
  // Attitude steps in hover (nominal vehicle, no calibration bias), 250 Hz log.
  {
    model::VehicleParams nominal = v;
    nominal.bias = {};
    nominal.has_bias = false;
    sim::World world(SynthWorld(nominal, 50.0));
    const double weight = v.mass * kGravity;
    world.SetCommand(0, {weight, 0.0, 0.0, 0.0});
    world.Step(0.5);
    std::vector<std::vector<double>> cols(7);
    const std::array<double, 3> amp{0.10, 0.10, 0.02};
    double t0 = world.time();
    auto run = [&](const Vec3& ref, double duration) {
      const double thrust = weight / (std::cos(ref.x()) * std::cos(ref.y()));
      world.SetCommand(0, {thrust, ref.x(), ref.y(), ref.z()});
      const int n = static_cast<int>(std::lround(duration * 250.0));
      for (int k = 0; k < n; ++k) {
        const sim::TrueState s = world.GetTrueState(0);
        cols[0].push_back(world.time() - t0);
        for (int i = 0; i < 3; ++i) cols[1 + i].push_back(ref[i]);
        for (int i = 0; i < 3; ++i) cols[4 + i].push_back(s.euler[i] + 0.001 * normal(rng));
        world.Step(0.004);
      }
    };
    run(Vec3::Zero(), 0.4);
    for (int a = 0; a < 3; ++a) {
      for (double sgn : {1.0, 0.0, -1.0, 0.0}) {
        Vec3 ref = Vec3::Zero();
        ref[a] = sgn * amp[a];
        run(ref, 1.2);
      }
    }
    sysid_report::WriteCsv(dir / "attitude_steps.csv",
                           {"t", "roll_ref", "pitch_ref", "yaw_ref", "roll", "pitch", "yaw"}, cols);
  }
  // Closed-loop flight of the biased vehicle: position PD from noisy mocap at 50 Hz with
  // attitude doublets and thrust steps on top, commands and measured state logged.
  {
    sim::World world(SynthWorld(v, 50.0));
    std::vector<std::vector<double>> cols(15);
    const double dt = 0.02, kp = 2.0, kd = 2.5;
    const int n = 1000;  // 20 s
    for (int k = 0; k < n; ++k) {
      const double t = k * dt;
      const sim::TrueState s = world.GetTrueState(0);
      Vec<9> z;
      for (int i = 0; i < 3; ++i) {
        z[i] = s.position[i] + 0.001 * normal(rng);
        z[3 + i] = s.velocity[i] + 0.01 * normal(rng);
        z[6 + i] = s.euler[i] + 0.002 * normal(rng);
      }
      const int leg = static_cast<int>(t / 4.0);
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
      world.SetCommand(0, {thrust, roll, pitch, yaw_cmd});
      cols[0].push_back(t);
      for (int i = 0; i < 9; ++i) cols[1 + i].push_back(z[i]);
      cols[10].push_back(thrust);
      cols[11].push_back(roll);
      cols[12].push_back(pitch);
      cols[13].push_back(yaw_cmd);
      cols[14].push_back(s.voltage);
      world.Step(dt);
    }
    sysid_report::WriteCsv(dir / "flight.csv",
                           {"t", "x", "y", "z", "vx", "vy", "vz", "roll", "pitch", "yaw",
                            "thrust_cmd", "roll_cmd", "pitch_cmd", "yaw_cmd", "voltage"},
                           cols);
  }
  {
    std::ofstream out(dir / "campaign.yaml");
    out << "# Synthetic campaign written by `fnmpc sysid synth` (truth: truth.yaml)\n"
        << "name: synthetic-storm-drone\n"
        << fmt::format("mass: {}\n", v.mass) << fmt::format("arm_length: {}\n", v.arm_length)
        << "propeller_bench: bench.csv\n"
        << "pendulum:\n"
        << fmt::format("  wire_separation: {}\n  wire_length: {}\n", d, L)
        << "  runs: {x: pendulum_x.csv, y: pendulum_y.csv, z: pendulum_z.csv}\n"
        << "attitude_steps: attitude_steps.csv\n"
        << "flight: flight.csv\n";
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
  sub->add_option("campaign", o->campaign, "campaign YAML (shared/data-formats.md)");
  sub->add_option("-o,--output", o->output, "vehicle YAML to write");
  sub->add_flag("!--no-plots", o->plots, "skip tools/sysid_report.py (CSV dumps only)");
  sub->add_option("--motor-time-constant", o->motor_time_constant,
                  "simulator motor lag for the PD fit [s]");
  sub->add_option("--autopilot-rate", o->autopilot_rate_hz, "simulator autopilot rate [Hz]");
  sub->add_option("--physics-dt", o->physics_dt, "simulator physics step [s]");
  sub->add_flag("--lag-only", o->lag_only,
                "write the first-order lag tau without the fitted delay (when the delay is a "
                "logging artefact); default: tau + delay");
#if defined(FNMPC_HAVE_SIM)
  CLI::App* synth =
      sub->add_subcommand("synth", "Write a synthetic campaign made with the simulator");
  synth->add_option("outdir", o->synth_dir, "output directory")->required();
  synth->add_option("--seed", o->seed, "noise seed");
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

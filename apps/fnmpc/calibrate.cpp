// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc calibrate VEHICLE.yaml FLIGHT.csv -o calibrated.yaml`: roll/pitch biases and thrust
// scale from a logged flight by windowed open-loop predictions (docs/sysid.md).
#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "apps/fnmpc/sysid_report.hpp"
#include "fnmpc/config/csv_reader.hpp"
#include "fnmpc/config/output_files.hpp"
#include "fnmpc/config/vehicle_yaml.hpp"
#include "fnmpc/sysid/angles.hpp"
#include "fnmpc/sysid/calibration.hpp"

namespace fnmpc::app {

namespace fs = std::filesystem;

namespace {

struct CalibrateOptions {
  std::string vehicle;
  std::string flight;
  std::string output;
  bool plots = true;
  sysid::CalibrationSettings settings;
};

int RunCalibrate(const CalibrateOptions& o) {
  const model::VehicleParams v = config::LoadVehicleFile(o.vehicle);
  const std::vector<std::string> cols{"t",          "x",        "y",         "z",       "vx",
                                      "vy",         "vz",       "roll",      "pitch",   "yaw",
                                      "thrust_cmd", "roll_cmd", "pitch_cmd", "yaw_cmd", "voltage"};
  const config::CsvTable csv = config::ReadCsv(o.flight, cols, "t");
  sysid::FlightLog log;
  log.t = csv.Column("t");
  log.voltage = csv.Column("voltage");
  for (std::size_t i = 0; i < csv.rows(); ++i) {
    Vec<9> x;
    for (int k = 0; k < 9; ++k) x[k] = csv.Column(cols[1 + k])[i];
    Vec<4> u;
    for (int k = 0; k < 4; ++k) u[k] = csv.Column(cols[10 + k])[i];
    // Yaw continuous along the log (the model has no wrapping).
    if (i > 0) {
      x[8] = sysid::UnwrapNear(x[8], log.state.back()[8]);
      u[3] = sysid::UnwrapNear(u[3], log.command.back()[3]);
    }
    log.state.push_back(x);
    log.command.push_back(u);
  }
  const sysid::CalibrationResult r = sysid::Calibrate(v, log, o.settings);
  if (!r.converged) throw std::runtime_error("calibrate: the optimisation did not converge");
  model::VehicleParams out = v;
  out.bias = r.bias;
  out.has_bias = true;
  out.Validate();

  const auto before = sysid::PredictWindows(v, log, o.settings);
  const auto after = sysid::PredictWindows(out, log, o.settings);
  const fs::path final_dir = sysid_report::ReportDir(o.output);
  const fs::path dir = sysid_report::MakeTemp(final_dir);
  bool sane = true;
  {
    std::vector<std::vector<double>> w(11);
    for (std::size_t k = 0; k < before.size(); ++k) {
      for (std::size_t j = 0; j < before[k].state.size(); ++j) {
        const std::size_t i = static_cast<std::size_t>(before[k].start) + j;
        w[0].push_back(static_cast<double>(k));
        w[1].push_back(log.t[i]);
        for (int a = 0; a < 3; ++a) {
          w[2 + a].push_back(log.state[i][a]);
          w[5 + a].push_back(before[k].state[j][a]);
          w[8 + a].push_back(after[k].state[j][a]);
        }
      }
    }
    sysid_report::WriteCsv(dir / "windows.csv",
                           {"window", "t", "x", "y", "z", "x_before", "y_before", "z_before",
                            "x_after", "y_after", "z_after"},
                           w);
    std::vector<std::vector<double>> c(10);
    for (std::size_t i = 0; i < log.t.size(); ++i) {
      c[0].push_back(log.t[i]);
      c[1].push_back(log.command[i][0]);
      c[2].push_back(log.command[i][1]);
      c[3].push_back(log.command[i][2]);
      c[4].push_back(v.bias.thrust_scale * log.command[i][0]);
      c[5].push_back(r.bias.thrust_scale * log.command[i][0]);
      c[6].push_back(log.command[i][1] + r.bias.roll);
      c[7].push_back(log.command[i][2] + r.bias.pitch);
      c[8].push_back(log.state[i][6]);
      c[9].push_back(log.state[i][7]);
    }
    sysid_report::WriteCsv(dir / "commands.csv",
                           {"t", "thrust_cmd", "roll_cmd", "pitch_cmd", "thrust_before",
                            "thrust_after", "roll_after", "pitch_after", "roll", "pitch"},
                           c);
    sysid_report::Stage stage("calibration");
    stage.ok = true;
    // The larger of the covariance and the window-bootstrap standard errors.
    std::array<double, 3> se{};
    for (int k = 0; k < 3; ++k) {
      se[k] = std::isfinite(r.bootstrap_std_error[k])
                  ? std::max(r.std_error[k], r.bootstrap_std_error[k])
                  : r.std_error[k];
    }
    stage.Param("bias roll", r.bias.roll, se[0], "rad");
    stage.Param("bias pitch", r.bias.pitch, se[1], "rad");
    stage.Param("thrust scale", r.bias.thrust_scale, se[2], "-");
    stage.residuals = {{"position_error_before", r.position_error_before},
                       {"position_error_after", r.position_error_after},
                       {"rms_scaled", r.rms_scaled},
                       {"covariance_std_error", r.std_error},
                       {"bootstrap_std_error", r.bootstrap_std_error},
                       {"bootstrap_refits", o.settings.bootstrap},
                       {"windows", r.windows}};
    stage.Check("mean position error after / before",
                r.position_error_after / r.position_error_before, 1.0);
    stage.CheckTrue("estimates inside their bounds", !r.at_bound,
                    fmt::format("roll {:.4f}, pitch {:.4f}, scale {:.4f}", r.bias.roll,
                                r.bias.pitch, r.bias.thrust_scale));
    stage.Check("abs(thrust scale - 1)", std::abs(r.bias.thrust_scale - 1.0), 0.3);
    stage.Check("std error of the roll bias [rad]", se[0], 0.005);
    stage.Check("std error of the pitch bias [rad]", se[1], 0.005);
    stage.Check("std error of the thrust scale", se[2], 0.01);
    sane = stage.Passed();
    nlohmann::json j;
    j["kind"] = "calibrate";
    j["stages"] = nlohmann::json::array({stage.Json()});
    j["vehicle"] = o.vehicle;
    j["flight"] = o.flight;
    j["bias_roll"] = r.bias.roll;
    j["bias_pitch"] = r.bias.pitch;
    j["thrust_scale"] = r.bias.thrust_scale;
    j["position_error_before"] = r.position_error_before;
    j["position_error_after"] = r.position_error_after;
    j["windows"] = r.windows;
    j["window"] = o.settings.window;
    j["window_stride"] = o.settings.window_stride;
    config::WriteFileAtomically((dir / "summary.json").string(), j.dump(2) + "\n");
  }
  sysid_report::Finalize(dir, final_dir, o.plots);
  config::SaveVehicleFile(out, o.output);
  fmt::print("{}: calibrated from {} ({} windows of {} s)\n", o.output, o.flight, r.windows,
             o.settings.window);
  fmt::print("  bias roll {:.5f} rad ({:.3f} deg), pitch {:.5f} rad ({:.3f} deg), thrust {:.4f}\n",
             r.bias.roll, r.bias.roll * 180.0 / M_PI, r.bias.pitch, r.bias.pitch * 180.0 / M_PI,
             r.bias.thrust_scale);
  fmt::print("  mean position error of the predictions: before {:.4f} m, after {:.4f} m\n",
             r.position_error_before, r.position_error_after);
  fmt::print(
      "  standard errors (covariance / window bootstrap): roll {:.2g} / {:.2g} rad, pitch {:.2g} "
      "/ {:.2g} rad, thrust {:.2g} / {:.2g}\n",
      r.std_error[0], r.bootstrap_std_error[0], r.std_error[1], r.bootstrap_std_error[1],
      r.std_error[2], r.bootstrap_std_error[2]);
  fmt::print("  sanity checks {}\n", sane ? "PASS" : "FAIL (see the report)");
  fmt::print("  report: {}\n", final_dir.string());
  return sane ? 0 : 3;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto o = std::make_shared<CalibrateOptions>();
  CLI::App* sub = app.add_subcommand(
      "calibrate", "Estimate attitude biases and thrust scale from a flight (docs/sysid.md)");
  sub->add_option("vehicle", o->vehicle, "vehicle YAML")->required();
  sub->add_option("flight", o->flight, "flight CSV (docs/data-formats.md)")->required();
  sub->add_option("-o,--output", o->output, "calibrated vehicle YAML to write")->required();
  sub->add_flag("!--no-plots", o->plots, "skip tools/sysid_report.py (CSV dumps only)");
  sub->add_option("--window", o->settings.window, "prediction window [s]")
      ->check(FiniteIn(0.01, 60.0));
  sub->add_option("--stride", o->settings.window_stride, "window start spacing [s]")
      ->check(FiniteIn(0.01, 60.0));
  o->settings.bootstrap = 30;
  sub->add_option("--bootstrap", o->settings.bootstrap,
                  "refits on resampled windows for the standard errors (0: covariance only)");
  registry.push_back({sub, [o] { return RunCalibrate(*o); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/vehicle_yaml.hpp"

#include <fmt/core.h>

#include "fnmpc/core/types.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace fnmpc::config {

namespace {

double Positive(YamlMap& m, const std::string& key) {
  const double v = m.Double(key);
  if (!(v > 0.0)) throw m.ErrorAt(key, "must be > 0, got " + std::to_string(v));
  return v;
}

Eigen::Vector3d Positive3(YamlMap& m, const std::string& key) {
  const Eigen::Vector3d v = m.Vector3(key);
  if (!(v.array() > 0.0).all()) throw m.ErrorAt(key, "every entry must be > 0");
  return v;
}

Eigen::Vector3d NonNegative3(YamlMap& m, const std::string& key) {
  const Eigen::Vector3d v = m.Vector3(key);
  if (!(v.array() >= 0.0).all()) throw m.ErrorAt(key, "every entry must be >= 0");
  return v;
}

}  // namespace

void CheckVehiclePlausible(const model::VehicleParams& p, const YamlMap& map) {
  const double hover = p.mass * kPlausibleGravity / 4.0;  // one rotor's thrust in hover [N]
  const auto [v_lo, v_hi] = kPlausibleVoltageRange;
  for (int k = 0; k <= 8; ++k) {
    const double volt = v_lo + (v_hi - v_lo) * k / 8.0;
    const double thr = p.throttle.Throttle(hover, volt);
    if (!(thr > 0.0 && thr < 1.0)) {
      throw map.ErrorAt("throttle_polynomial",
                        fmt::format("hover throttle at {:.2f} V is {:.4g}, must be in (0, 1) for "
                                    "the battery range {:.1f}-{:.1f} V (mass {:.4g} kg)",
                                    volt, thr, v_lo, v_hi, p.mass));
    }
    const double thr_max = p.throttle.Throttle(kThrustMargin * hover, volt);
    if (!(thr_max > thr && thr_max < 1.0)) {
      throw map.ErrorAt(
          "throttle_polynomial",
          fmt::format("at {:.2f} V full throttle gives less than {:.1f} x the hover thrust "
                      "(throttle {:.4g} at {:.4g} N per rotor, hover {:.4g} N)",
                      volt, kThrustMargin, thr_max, kThrustMargin * hover, hover));
    }
  }
}

model::VehicleParams ParseVehicle(YamlMap map) {
  model::VehicleParams p;
  p.mass = Positive(map, "mass");
  if (p.mass > 100.0) throw map.ErrorAt("mass", "must be <= 100 kg, got " + std::to_string(p.mass));
  p.inertia = Positive3(map, "inertia");
  if (const std::string why = model::UnrealisableInertia(p.inertia); !why.empty()) {
    throw map.ErrorAt("inertia", why);
  }
  p.thrust_constant = Positive(map, "thrust_constant");
  p.torque_constant = Positive(map, "torque_constant");
  {
    YamlMap poly = map.Map("throttle_polynomial");
    const YAML::Node rows = poly.Node("coefficients");
    if (!rows.IsSequence() || rows.size() != 4) {
      throw poly.ErrorAt("coefficients", "expected 4 rows (powers of thrust 0..3)");
    }
    for (int i = 0; i < 4; ++i) {
      const YAML::Node row = rows[i];
      if (!row.IsSequence() || static_cast<int>(row.size()) != 4 - i) {
        throw poly.ErrorAt("coefficients",
                           "row " + std::to_string(i) + " must hold " + std::to_string(4 - i) +
                               " numbers (powers of voltage 0.." + std::to_string(3 - i) + ")");
      }
      for (int j = 0; j < 4 - i; ++j) {
        double c = kNaN;
        try {
          c = row[j].as<double>();
        } catch (const YAML::Exception&) {
        }
        if (!std::isfinite(c)) {
          throw ConfigError(
              fmt::format("{}:{}:{}: key 'throttle_polynomial.coefficients': row {} "
                          "entry {} is not a finite number",
                          map.file(), row[j].Mark().line + 1, row[j].Mark().column + 1, i, j));
        }
        p.throttle.c(i, j) = c;
      }
    }
    poly.Finish();
  }
  {
    YamlMap att = map.Map("attitude");
    p.attitude_time_constant = Positive3(att, "time_constant");
    p.attitude_gain = Positive3(att, "gain");
    att.Finish();
  }
  {
    YamlMap pd = map.Map("attitude_pd");
    p.attitude_kp = NonNegative3(pd, "kp");
    p.attitude_kd = NonNegative3(pd, "kd");
    pd.Finish();
  }
  p.arm_length = Positive(map, "arm_length");
  if (map.Has("bias")) {
    YamlMap bias = map.Map("bias");
    p.bias.roll = bias.Double("roll");
    p.bias.pitch = bias.Double("pitch");
    p.bias.thrust_scale = Positive(bias, "thrust");
    bias.Finish();
    p.has_bias = true;
  }
  map.Finish();
  try {
    p.Validate();
  } catch (const std::invalid_argument& e) {
    throw map.ErrorAt("mass", e.what());  // the file as a whole; reported at its first key
  }
  CheckVehiclePlausible(p, map);
  return p;
}

model::VehicleParams LoadVehicleFile(const std::string& path) {
  return ParseVehicle(YamlMap::LoadFile(path));
}

namespace {
std::string Triple(const Eigen::Vector3d& v) {
  std::ostringstream os;
  os << std::setprecision(10) << "[" << v[0] << ", " << v[1] << ", " << v[2] << "]";
  return os.str();
}
}  // namespace

void SaveVehicleFile(const model::VehicleParams& p, const std::string& path) {
  std::ostringstream os;
  os << std::setprecision(10);
  os << "mass: " << p.mass << "\n";
  os << "inertia: " << Triple(p.inertia) << "        # kg m^2, body x y z\n";
  os << "thrust_constant: " << p.thrust_constant << "        # N / rpm^2\n";
  os << "torque_constant: " << p.torque_constant << "        # N m / rpm^2\n";
  os << "throttle_polynomial:        # throttle = sum c[i][j] f^i V^j, i + j <= 3\n";
  os << "  coefficients:\n";
  for (int i = 0; i < 4; ++i) {
    os << "    - [";
    for (int j = 0; j < 4 - i; ++j) os << (j ? ", " : "") << p.throttle.c(i, j);
    os << "]\n";
  }
  os << "attitude:\n  time_constant: " << Triple(p.attitude_time_constant)
     << "\n  gain: " << Triple(p.attitude_gain) << "\n";
  os << "attitude_pd:\n  kp: " << Triple(p.attitude_kp) << "\n  kd: " << Triple(p.attitude_kd)
     << "\n";
  os << "arm_length: " << p.arm_length << "\n";
  if (p.has_bias) {
    os << "bias:\n  roll: " << p.bias.roll << "\n  pitch: " << p.bias.pitch
       << "\n  thrust: " << p.bias.thrust_scale << "\n";
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    if (!out) throw ConfigError(path + ": cannot write file");
    out << os.str();
    out.flush();
    if (!out) throw ConfigError(tmp + ": write failed: " + std::strerror(errno));
    out.close();
    if (!out) throw ConfigError(tmp + ": write failed: " + std::strerror(errno));
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace fnmpc::config

// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/vehicle_yaml.hpp"

#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace fnmpc::config {

model::VehicleParams ParseVehicle(YamlMap map) {
  model::VehicleParams p;
  p.mass = map.Double("mass");
  p.inertia = map.Vector3("inertia");
  p.thrust_constant = map.Double("thrust_constant");
  p.torque_constant = map.Double("torque_constant");
  {
    YamlMap poly = map.Map("throttle_polynomial");
    const YAML::Node rows = poly.Node("coefficients");
    if (!rows.IsSequence() || rows.size() != 4) {
      throw poly.ErrorAt("coefficients", "expected 4 rows (powers of thrust 0..3)");
    }
    for (int i = 0; i < 4; ++i) {
      const YAML::Node row = rows[i];
      if (!row.IsSequence() || static_cast<int>(row.size()) != 4 - i) {
        throw poly.ErrorAt("coefficients", "row " + std::to_string(i) + " must hold " +
                                               std::to_string(4 - i) +
                                               " numbers (powers of voltage 0.." +
                                               std::to_string(3 - i) + ")");
      }
      for (int j = 0; j < 4 - i; ++j) {
        try {
          p.throttle.c(i, j) = row[j].as<double>();
        } catch (const YAML::Exception&) {
          throw poly.ErrorAt("coefficients", "row " + std::to_string(i) + " entry " +
                                                 std::to_string(j) + " is not a number");
        }
      }
    }
    poly.Finish();
  }
  {
    YamlMap att = map.Map("attitude");
    p.attitude_time_constant = att.Vector3("time_constant");
    p.attitude_gain = att.Vector3("gain");
    att.Finish();
  }
  {
    YamlMap pd = map.Map("attitude_pd");
    p.attitude_kp = pd.Vector3("kp");
    p.attitude_kd = pd.Vector3("kd");
    pd.Finish();
  }
  p.arm_length = map.Double("arm_length");
  if (map.Has("bias")) {
    YamlMap bias = map.Map("bias");
    p.bias.roll = bias.Double("roll");
    p.bias.pitch = bias.Double("pitch");
    p.bias.thrust_scale = bias.Double("thrust");
    bias.Finish();
    p.has_bias = true;
  }
  map.Finish();
  try {
    p.Validate();
  } catch (const std::invalid_argument& e) {
    throw map.Error(e.what());
  }
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
    if (!out) throw ConfigError(path + ": write failed");
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace fnmpc::config

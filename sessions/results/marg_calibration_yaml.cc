#include "sessions/results/marg_calibration_yaml.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "common/text_io.h"
#include "common/yaml_fields.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::results {

namespace fs = std::filesystem;

namespace {

std::string FormatDouble(double v) { return common::ShortestDouble(v); }

constexpr const char* kCalibrationFormat = "msmcal-marg-calibration/1";

void EmitVec(YAML::Emitter& out, const Eigen::Vector3d& v) {
  out << YAML::Flow << YAML::BeginSeq << FormatDouble(v.x()) << FormatDouble(v.y())
      << FormatDouble(v.z()) << YAML::EndSeq;
}
void EmitMat(YAML::Emitter& out, const Eigen::Matrix3d& m) {
  out << YAML::BeginSeq;
  for (int r = 0; r < 3; ++r) EmitVec(out, m.row(r).transpose());
  out << YAML::EndSeq;
}

}  // namespace

std::string FormatMargCalibrationYaml(const MargCalibrationFile& file,
                                      const MargValidationFigures& val) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kCalibrationFormat;
  out << YAML::Key << "model" << YAML::Value
      << "calibrated = alignment * compensation * (raw - offset)";
  if (file.field_elevation_deg) {
    out << YAML::Key << "field_elevation_deg" << YAML::Value
        << FormatDouble(*file.field_elevation_deg);
  }
  out << YAML::Key << "sensors" << YAML::Value << YAML::BeginMap;
  const std::tuple<const char*, const char*, const std::optional<marg::SensorCalibration>*>
      sensors[] = {{"accelerometer", "g", &file.calibration.accelerometer},
                   {"gyroscope", "dps", &file.calibration.gyroscope},
                   {"magnetometer", "uT", &file.calibration.magnetometer}};
  for (const auto& [name, unit, cal] : sensors) {
    if (!cal->has_value()) continue;
    const marg::SensorCalibration& c = **cal;
    out << YAML::Key << name << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "units" << YAML::Value << unit;
    out << YAML::Key << "offset" << YAML::Value;
    EmitVec(out, c.offset);
    out << YAML::Key << "compensation" << YAML::Value;
    EmitMat(out, c.compensation);
    out << YAML::Key << "alignment" << YAML::Value;
    EmitMat(out, c.alignment);
    out << YAML::Key << "figures" << YAML::Value << YAML::BeginMap;
    if (std::string(name) != "gyroscope") {
      out << YAML::Key << "sphere_radius" << YAML::Value << FormatDouble(c.sphere_radius);
      out << YAML::Key << "ellipsoid_semi_axes" << YAML::Value;
      EmitVec(out, c.ellipsoid.semi_axes);
      out << YAML::Key << "ellipsoid_axes_columns" << YAML::Value;
      EmitMat(out, c.ellipsoid.axes);
      out << YAML::Key << "ellipsoid_rms_radial_residual" << YAML::Value
          << FormatDouble(c.ellipsoid_rms_residual);
      out << YAML::Key << "ellipsoid_inliers" << YAML::Value << c.ellipsoid_inliers;
      out << YAML::Key << "ellipsoid_samples" << YAML::Value << c.ellipsoid_samples;
      out << YAML::Key << "ellipsoid_condition_number" << YAML::Value
          << FormatDouble(c.ellipsoid_condition);
      out << YAML::Key << "sphere_coverage" << YAML::Value << FormatDouble(c.coverage);
      out << YAML::Key << "norm_relative_std" << YAML::Value << FormatDouble(c.norm_relative_std);
      out << YAML::Key << "plane_rms_residual" << YAML::Value << FormatDouble(c.plane_rms_residual);
      out << YAML::Key << "plane_turn_deg" << YAML::Value << FormatDouble(c.plane_turn_deg);
    }
    out << YAML::Key << "alignment_roll_deg" << YAML::Value << FormatDouble(c.alignment_roll_deg);
    out << YAML::Key << "alignment_pitch_deg" << YAML::Value << FormatDouble(c.alignment_pitch_deg);
    out << YAML::EndMap;
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  if (val.present) {
    out << YAML::Key << "validation" << YAML::Value << YAML::BeginMap;
    if (std::isfinite(val.cost[0])) {  // needs the accelerometer
      out << YAML::Key << "mean_cost_raw" << YAML::Value << FormatDouble(val.cost[0]);
      out << YAML::Key << "mean_cost_compensated" << YAML::Value << FormatDouble(val.cost[1]);
      out << YAML::Key << "mean_cost_aligned_compensated" << YAML::Value
          << FormatDouble(val.cost[2]);
    }
    out << YAML::Key << "magnetometer_norm_relative_std" << YAML::Value
        << FormatDouble(val.mag_norm_relative_std);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

namespace {

common::YamlFields Fields(const fs::path& file) {
  return common::YamlFields(file.string(),
                            [](const std::string& m) { throw interchange::InterchangeError(m); });
}

// "<file>:<line>: <what>" as an InterchangeError.
[[noreturn]] void YamlFail(const fs::path& file, const YAML::Node& node, const std::string& what) {
  Fields(file).FailText(node, what);
}

Eigen::Vector3d ReadVec(const fs::path& file, const YAML::Node& parent, const std::string& key,
                        const std::string& where) {
  const YAML::Node n = parent[key];
  if (!n || !n.IsSequence() || n.size() != 3) {
    YamlFail(file, n ? n : parent, where + "." + key + ": expected a sequence of 3 numbers");
  }
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) {
    try {
      v(i) = n[i].as<double>();
    } catch (const YAML::Exception&) {
      YamlFail(file, n[i], where + "." + key + "[" + std::to_string(i) + "]: expected a number");
    }
  }
  return v;
}

}  // namespace

MargCalibrationFile ReadMargCalibrationYaml(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw interchange::InterchangeError(file.string() + ": cannot open");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseMargCalibrationYaml(text.str(), file);
}

MargCalibrationFile ParseMargCalibrationYaml(const std::string& text, const fs::path& file) {
  const YAML::Node root = Fields(file).Load(text);
  if (!root.IsMap()) YamlFail(file, root, "expected a mapping");
  if (!root["format"] || root["format"].as<std::string>("") != kCalibrationFormat) {
    YamlFail(file, root["format"] ? root["format"] : root,
             std::string("format: expected '") + kCalibrationFormat + "'");
  }
  MargCalibrationFile out;
  if (const YAML::Node e = root["field_elevation_deg"]) {
    try {
      out.field_elevation_deg = e.as<double>();
    } catch (const YAML::Exception&) {
      YamlFail(file, e, "field_elevation_deg: expected a number");
    }
  }
  const YAML::Node sensors = root["sensors"];
  if (!sensors || !sensors.IsMap()) YamlFail(file, root, "sensors: expected a map");
  auto read_sensor = [&](const char* name, std::optional<marg::SensorCalibration>* dst) {
    const YAML::Node s = sensors[name];
    if (!s) return;
    const std::string where = std::string("sensors.") + name;
    if (!s.IsMap()) YamlFail(file, s, where + ": expected a mapping");
    marg::SensorCalibration c;
    // Sequences of sequences: index rows by number.
    c.offset = ReadVec(file, s, "offset", where);
    auto mat = [&](const char* key) {
      const YAML::Node n = s[key];
      if (!n || !n.IsSequence() || n.size() != 3) {
        YamlFail(file, n ? n : s, where + "." + key + ": expected 3 rows of 3 numbers");
      }
      Eigen::Matrix3d m;
      for (int r = 0; r < 3; ++r) {
        const YAML::Node row = n[r];
        if (!row.IsSequence() || row.size() != 3) {
          YamlFail(file, row,
                   where + "." + key + "[" + std::to_string(r) + "]: expected 3 numbers");
        }
        for (int k = 0; k < 3; ++k) {
          try {
            m(r, k) = row[k].as<double>();
          } catch (const YAML::Exception&) {
            YamlFail(file, row[k],
                     where + "." + key + "[" + std::to_string(r) + "][" + std::to_string(k) +
                         "]: expected a number");
          }
        }
      }
      return m;
    };
    c.compensation = mat("compensation");
    c.alignment = mat("alignment");
    *dst = c;
  };
  read_sensor("accelerometer", &out.calibration.accelerometer);
  read_sensor("gyroscope", &out.calibration.gyroscope);
  read_sensor("magnetometer", &out.calibration.magnetometer);
  if (!out.calibration.magnetometer && !out.calibration.accelerometer) {
    YamlFail(file, sensors, "sensors: neither magnetometer nor accelerometer present");
  }
  return out;
}

}  // namespace msmcal::results

#include "mocks/marg/marg_simulator.h"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

#include "common/number_format.h"
#include "common/text_io.h"
#include "common/units.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::sim {
namespace {

std::string Fmt(double v) { return common::FormatSignificant(v, 6); }

std::string Exact(double v) { return common::ShortestDouble(v); }

Eigen::Vector3d Gaussian3(std::mt19937_64& rng, double sigma) {
  std::normal_distribution<double> n(0.0, sigma);
  return {n(rng), n(rng), n(rng)};
}

Eigen::Quaterniond UniformRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Vector4d v(n(rng), n(rng), n(rng), n(rng));
  v.normalize();
  return Eigen::Quaterniond(v(0), v(1), v(2), v(3));
}

// The fixed plane's orientation: rotation by tilt about the horizontal axis at azimuth.
Eigen::Quaterniond PlaneOrientation(double tilt_deg, double azimuth_deg) {
  const Eigen::Vector3d axis(std::cos(azimuth_deg * common::kRadPerDeg),
                             std::sin(azimuth_deg * common::kRadPerDeg), 0);
  return Eigen::Quaterniond(Eigen::AngleAxisd(tilt_deg * common::kRadPerDeg, axis));
}

struct Sampler {
  const MargSimConfig& cfg;
  const MargTruth& truth;
  std::mt19937_64& rng;

  dataset::MargSample Sample(double t_s, const Eigen::Quaterniond& earth_from_board,
                             const Eigen::Vector3d& rate_dps) {
    const Eigen::Quaterniond board_from_earth = earth_from_board.conjugate();
    const Eigen::Vector3d g = board_from_earth * truth.gravity_in_earth;
    const Eigen::Vector3d b = board_from_earth * truth.field_in_earth;
    const Eigen::Vector3d a =
        cfg.accelerometer.Distort(g) + Gaussian3(rng, cfg.accelerometer.noise_std);
    const Eigen::Vector3d w =
        cfg.gyroscope.Distort(rate_dps) + Gaussian3(rng, cfg.gyroscope.noise_std);
    const Eigen::Vector3d m =
        cfg.magnetometer.Distort(b) + Gaussian3(rng, cfg.magnetometer.noise_std);
    dataset::MargSample s;
    s.t_s = t_s;
    if (!cfg.magnetometer_only) {
      s.ax_g = a.x(), s.ay_g = a.y(), s.az_g = a.z();
      s.gx_dps = w.x(), s.gy_dps = w.y(), s.gz_dps = w.z();
    }
    s.mx_uT = m.x(), s.my_uT = m.y(), s.mz_uT = m.z();
    return s;
  }

  // Board on a fixed plane, turning about its Z axis with a slightly non-uniform rate.
  void PlaneRotation(double tilt_deg, double azimuth_deg, double turns, double duration_s,
                     dataset::MargRecording* rec, MargRecordingTruth* tr) {
    const Eigen::Quaterniond plane = PlaneOrientation(tilt_deg, azimuth_deg);
    std::uniform_real_distribution<double> u(0, 2 * std::numbers::pi);
    const double psi0 = u(rng);
    const int n = static_cast<int>(std::round(duration_s * cfg.sample_rate_hz));
    const double total = 2 * std::numbers::pi * turns;
    for (int i = 0; i < n; ++i) {
      const double t = i / cfg.sample_rate_hz;
      const double s = t / duration_s;
      const double psi = psi0 + total * (s + 0.03 * std::sin(2 * std::numbers::pi * s));
      const double psi_dot = total / duration_s *
                             (1 + 0.03 * 2 * std::numbers::pi * std::cos(2 * std::numbers::pi * s));
      const Eigen::Quaterniond q =
          plane * Eigen::Quaterniond(Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()));
      const Eigen::Vector3d rate(0, 0, psi_dot / common::kRadPerDeg);
      rec->samples.push_back(Sample(t, q, rate));
      tr->earth_from_board.push_back(q);
      tr->rate_board_dps.push_back(rate);
      tr->outlier.push_back(false);
    }
  }
};

}  // namespace

Eigen::Matrix3d SensorDistortion::SensorFromBoard() const {
  return geometry::So3Exp(misalignment_deg * common::kRadPerDeg);
}

Eigen::Vector3d SensorDistortion::Distort(const Eigen::Vector3d& v_board) const {
  return gain * (SensorFromBoard() * v_board) + offset;
}

SensorDistortion MargSimConfig::DefaultAccelerometer() {
  SensorDistortion d;
  d.misalignment_deg = Eigen::Vector3d(1.5, -1.0, 2.0);
  d.gain << 1.02, 0.010, -0.008,  //
      0.005, 0.97, 0.012,         //
      -0.010, 0.007, 1.01;
  d.offset = Eigen::Vector3d(0.03, -0.02, 0.05);
  d.noise_std = 0.004;  // g, ADXL345-like (3.9 mg/LSB)
  return d;
}

SensorDistortion MargSimConfig::DefaultGyroscope() {
  SensorDistortion d;
  d.misalignment_deg = Eigen::Vector3d(0.8, -0.5, 1.0);
  d.gain = Eigen::Vector3d(1.01, 0.99, 1.0).asDiagonal();
  d.offset = Eigen::Vector3d(0.5, -0.3, 0.2);
  d.noise_std = 0.05;  // dps
  return d;
}

SensorDistortion MargSimConfig::DefaultMagnetometer() {
  SensorDistortion d;
  d.misalignment_deg = Eigen::Vector3d(-2.0, 1.2, 3.0);
  d.gain << 1.10, 0.06, -0.04,  //
      0.03, 0.90, 0.05,         //
      -0.02, 0.04, 1.06;
  d.offset = Eigen::Vector3d(25.0, -12.0, 40.0);
  d.noise_std = 0.15;  // uT, HMC5883L-like (0.073 uT/LSB, ~2 LSB noise)
  return d;
}

std::string MargSimConfig::Validate() const {
  auto positive = [](const char* name, double v) -> std::string {
    return v > 0 ? "" : std::string(name) + "=" + Fmt(v) + " must be > 0";
  };
  for (const auto& e :
       {positive("sample_rate_hz", sample_rate_hz), positive("gravity_g", gravity_g),
        positive("field_uT", field_uT), positive("plane_turns", plane_turns),
        positive("plane_duration_s", plane_duration_s),
        positive("validation_turns", validation_turns),
        positive("validation_duration_s", validation_duration_s)}) {
    if (!e.empty()) return e;
  }
  if (std::abs(field_elevation_deg) > 90) {
    return "field_elevation_deg=" + Fmt(field_elevation_deg) + " must be in [-90, 90]";
  }
  if (free_orientations < 1) {
    return "free_orientations=" + std::to_string(free_orientations) + " must be >= 1";
  }
  if (free_samples_per_orientation < 1) {
    return "free_samples_per_orientation=" + std::to_string(free_samples_per_orientation) +
           " must be >= 1";
  }
  if (!(outlier_fraction >= 0 && outlier_fraction < 0.5)) {
    return "outlier_fraction=" + Fmt(outlier_fraction) + " must be in [0, 0.5)";
  }
  const std::pair<const char*, const SensorDistortion*> sensors[] = {
      {"accelerometer", &accelerometer},
      {"gyroscope", &gyroscope},
      {"magnetometer", &magnetometer}};
  for (const auto& [name, d] : sensors) {
    if (!(d->noise_std >= 0)) return std::string(name) + ".noise_std must be >= 0";
    if (!(d->gain.determinant() > 0)) {
      return std::string(name) + ".gain has determinant " + Fmt(d->gain.determinant()) +
             ", must be > 0";
    }
  }
  return "";
}

std::vector<Eigen::Vector3d> MargTruth::GravityInBoard(const MargRecordingTruth& rec) const {
  std::vector<Eigen::Vector3d> out;
  for (const auto& q : rec.earth_from_board) out.push_back(q.conjugate() * gravity_in_earth);
  return out;
}

std::vector<Eigen::Vector3d> MargTruth::FieldInBoard(const MargRecordingTruth& rec) const {
  std::vector<Eigen::Vector3d> out;
  for (const auto& q : rec.earth_from_board) out.push_back(q.conjugate() * field_in_earth);
  return out;
}

MargSimulation SimulateMarg(const MargSimConfig& config, uint64_t seed) {
  if (const std::string err = config.Validate(); !err.empty()) {
    throw std::invalid_argument("MargSimConfig: " + err);
  }
  MargSimulation sim;
  MargTruth& truth = sim.truth;
  truth.config = config;
  truth.seed = seed;
  truth.gravity_in_earth = Eigen::Vector3d(0, 0, config.gravity_g);
  const double el = config.field_elevation_deg * common::kRadPerDeg;
  truth.field_in_earth = config.field_uT * Eigen::Vector3d(std::cos(el), 0, std::sin(el));
  std::mt19937_64 rng(seed);
  Sampler sampler{config, truth, rng};
  for (auto* rec : {&sim.plane_rotation, &sim.free_rotation, &sim.validation}) {
    rec->has_inertial = !config.magnetometer_only;
  }

  sampler.PlaneRotation(config.plane_tilt_deg, config.plane_tilt_azimuth_deg, config.plane_turns,
                        config.plane_duration_s, &sim.plane_rotation, &truth.plane_rotation);

  std::uniform_real_distribution<double> unit(0, 1);
  int k = 0;
  for (int o = 0; o < config.free_orientations; ++o) {
    const Eigen::Quaterniond q = UniformRotation(rng);
    for (int s = 0; s < config.free_samples_per_orientation; ++s, ++k) {
      dataset::MargSample sample =
          sampler.Sample(k / config.sample_rate_hz, q, Eigen::Vector3d::Zero());
      const bool spike = unit(rng) < config.outlier_fraction;
      if (spike) {
        Eigen::Vector3d d =
            Gaussian3(rng, 1.0).normalized() * config.outlier_magnitude * config.field_uT;
        sample.mx_uT += d.x(), sample.my_uT += d.y(), sample.mz_uT += d.z();
      }
      sim.free_rotation.samples.push_back(sample);
      truth.free_rotation.earth_from_board.push_back(q);
      truth.free_rotation.rate_board_dps.push_back(Eigen::Vector3d::Zero());
      truth.free_rotation.outlier.push_back(spike);
    }
  }

  sampler.PlaneRotation(config.validation_tilt_deg, config.validation_tilt_azimuth_deg,
                        config.validation_turns, config.validation_duration_s, &sim.validation,
                        &truth.validation);
  return sim;
}

void WriteMargTruth(const std::filesystem::path& dir, const MargTruth& truth) {
  const std::filesystem::path file = dir / "truth" / "marg.yaml";
  auto vec = [](YAML::Emitter& out, const Eigen::Vector3d& v) {
    out << YAML::Flow << YAML::BeginSeq << Exact(v.x()) << Exact(v.y()) << Exact(v.z())
        << YAML::EndSeq;
  };
  auto mat = [&](YAML::Emitter& out, const Eigen::Matrix3d& m) {
    out << YAML::BeginSeq;
    for (int r = 0; r < 3; ++r) vec(out, m.row(r).transpose());
    out << YAML::EndSeq;
  };
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "seed" << YAML::Value << truth.seed;
  out << YAML::Key << "model" << YAML::Value
      << "raw = gain * Exp(misalignment) * v_board + offset + N(0, noise_std^2)";
  out << YAML::Key << "gravity_in_earth_g" << YAML::Value;
  vec(out, truth.gravity_in_earth);
  out << YAML::Key << "field_in_earth_uT" << YAML::Value;
  vec(out, truth.field_in_earth);
  out << YAML::Key << "earth_frame" << YAML::Value << "z up, x magnetic north";
  const std::pair<const char*, const SensorDistortion*> sensors[] = {
      {"accelerometer", &truth.config.accelerometer},
      {"gyroscope", &truth.config.gyroscope},
      {"magnetometer", &truth.config.magnetometer}};
  out << YAML::Key << "sensors" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, d] : sensors) {
    if (truth.config.magnetometer_only && std::string(name) != "magnetometer") continue;
    out << YAML::Key << name << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "misalignment_deg" << YAML::Value;
    vec(out, d->misalignment_deg);
    out << YAML::Key << "sensor_from_board" << YAML::Value;
    mat(out, d->SensorFromBoard());
    out << YAML::Key << "gain" << YAML::Value;
    mat(out, d->gain);
    out << YAML::Key << "offset" << YAML::Value;
    vec(out, d->offset);
    out << YAML::Key << "noise_std" << YAML::Value << Exact(d->noise_std);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  const std::pair<const char*, const MargRecordingTruth*> recs[] = {
      {"plane_rotation", &truth.plane_rotation},
      {"free_rotation", &truth.free_rotation},
      {"validation", &truth.validation}};
  out << YAML::Key << "recordings" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, rec] : recs) {
    out << YAML::Key << name << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "earth_from_board_wxyz" << YAML::Value << YAML::BeginSeq;
    for (const auto& q : rec->earth_from_board) {
      out << YAML::Flow << YAML::BeginSeq << Exact(q.w()) << Exact(q.x()) << Exact(q.y())
          << Exact(q.z()) << YAML::EndSeq;
    }
    out << YAML::EndSeq;
    out << YAML::Key << "outlier_rows" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (size_t i = 0; i < rec->outlier.size(); ++i) {
      if (rec->outlier[i]) {
        out << i;
      }
    }
    out << YAML::EndSeq;
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  out << YAML::EndMap;
  std::error_code ec;
  std::filesystem::create_directories(file.parent_path(), ec);
  if (ec)
    throw std::runtime_error(file.parent_path().string() + ": cannot create: " + ec.message());
  std::ofstream f(file);
  f << out.c_str() << "\n";
  f.close();
  if (!f) throw std::runtime_error(file.string() + ": write failed");
}

}  // namespace msmcal::sim

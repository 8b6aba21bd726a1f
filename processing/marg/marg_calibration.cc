#include "processing/marg/marg_calibration.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "common/number_format.h"
#include "common/units.h"
#include "processing/marg/attitude.h"

namespace msmcal::marg {
namespace {

std::string Fmt(double v) { return common::FormatSignificant(v, 4); }

using Getter = Eigen::Vector3d (*)(const dataset::MargSample&);

std::vector<Eigen::Vector3d> Column(const dataset::MargRecording& rec, Getter get) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(rec.samples.size());
  for (const auto& s : rec.samples) out.push_back(get(s));
  return out;
}

void Set(dataset::MargSample* s, Sensor sensor, const Eigen::Vector3d& v) {
  switch (sensor) {
    case Sensor::kAccelerometer:
      s->ax_g = v.x(), s->ay_g = v.y(), s->az_g = v.z();
      break;
    case Sensor::kGyroscope:
      s->gx_dps = v.x(), s->gy_dps = v.y(), s->gz_dps = v.z();
      break;
    case Sensor::kMagnetometer:
      s->mx_uT = v.x(), s->my_uT = v.y(), s->mz_uT = v.z();
      break;
  }
}

// Ellipsoid + plane alignment for one vector sensor. Returns "" on success, else the reason.
std::string CalibrateVectorSensor(const std::vector<Eigen::Vector3d>& free,
                                  const std::vector<Eigen::Vector3d>& plane, double norm,
                                  const MargCalibrationOptions& options, SensorCalibration* out,
                                  std::vector<Eigen::Vector3d>* missing) {
  const EllipsoidFitResult fit = FitEllipsoid(free, options.ellipsoid);
  if (!fit.ok()) {
    // Coverage hint around the samples' mean (the centre is unknown when the fit fails).
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : free) mean += p;
    if (!free.empty()) mean /= static_cast<double>(free.size());
    std::vector<Eigen::Vector3d> dirs;
    for (const auto& p : free) dirs.push_back(p - mean);
    *missing = SphereCoverage(dirs, options.coverage).missing_directions;
    return std::string("free_rotation: ellipsoid fit ") + ToString(fit.status) + ": " + fit.message;
  }
  const Ellipsoid& e = fit.ellipsoid;
  const double radius = norm > 0 ? norm : e.MeanRadius();
  out->ellipsoid = e;
  out->offset = e.centre;
  out->sphere_radius = radius;
  out->compensation = radius * e.UnitSphereMap();
  out->ellipsoid_rms_residual = fit.rms_radial_residual;
  out->ellipsoid_inliers = fit.num_inliers;
  out->ellipsoid_samples = static_cast<int>(free.size());
  out->ellipsoid_condition = fit.condition_number;

  std::vector<Eigen::Vector3d> dirs;
  std::vector<double> norms;
  for (size_t i = 0; i < free.size(); ++i) {
    if (!fit.inlier[i]) continue;
    const Eigen::Vector3d c = out->compensation * (free[i] - out->offset);
    dirs.push_back(c);
    norms.push_back(c.norm());
  }
  const CoverageResult cov = SphereCoverage(dirs, options.coverage);
  out->coverage = cov.fraction;
  double mean = 0, var = 0;
  for (double v : norms) mean += v;
  mean /= std::max<size_t>(1, norms.size());
  for (double v : norms) var += (v - mean) * (v - mean);
  var /= std::max<size_t>(1, norms.size());
  out->norm_relative_std = mean > 0 ? std::sqrt(var) / mean : 0;
  if (cov.fraction < options.min_coverage) {
    *missing = cov.missing_directions;
    return "free_rotation: sphere coverage " + Fmt(cov.fraction) + " < min_coverage " +
           Fmt(options.min_coverage) + " (" + std::to_string(cov.missing_directions.size()) +
           " directions missing)";
  }

  std::vector<Eigen::Vector3d> circle;
  circle.reserve(plane.size());
  for (const auto& p : plane) circle.push_back(out->compensation * (p - out->offset));
  const PlaneAlignmentResult pa = FitPlaneAlignment(circle, options.plane);
  if (!pa.ok()) {
    return std::string("plane_rotation: plane alignment ") + ToString(pa.status) + ": " +
           pa.message;
  }
  out->alignment = pa.alignment;
  out->alignment_roll_deg = pa.roll_rad * common::kDegPerRad;
  out->alignment_pitch_deg = pa.pitch_rad * common::kDegPerRad;
  out->plane_rms_residual = pa.rms_plane_residual;
  out->plane_turn_deg = pa.turn_deg;
  return "";
}

double MedianOf(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

const char* ToString(Sensor sensor) {
  switch (sensor) {
    case Sensor::kAccelerometer:
      return "accelerometer";
    case Sensor::kGyroscope:
      return "gyroscope";
    case Sensor::kMagnetometer:
      return "magnetometer";
  }
  return "unknown";
}

const char* ToString(Stage stage) {
  switch (stage) {
    case Stage::kRaw:
      return "raw";
    case Stage::kCompensated:
      return "compensated";
    case Stage::kAlignedCompensated:
      return "aligned_compensated";
  }
  return "unknown";
}

Eigen::Vector3d Accel(const dataset::MargSample& s) { return {s.ax_g, s.ay_g, s.az_g}; }
Eigen::Vector3d Gyro(const dataset::MargSample& s) { return {s.gx_dps, s.gy_dps, s.gz_dps}; }
Eigen::Vector3d Mag(const dataset::MargSample& s) { return {s.mx_uT, s.my_uT, s.mz_uT}; }

Eigen::Vector3d SensorCalibration::Apply(const Eigen::Vector3d& raw, Stage stage) const {
  switch (stage) {
    case Stage::kRaw:
      return raw;
    case Stage::kCompensated:
      return compensation * (raw - offset);
    case Stage::kAlignedCompensated:
      return alignment * (compensation * (raw - offset));
  }
  return raw;
}

std::string MargCalibrationOptions::Validate() const {
  if (auto e = ellipsoid.Validate(); !e.empty()) return "ellipsoid." + e;
  if (auto e = plane.Validate(); !e.empty()) return "plane." + e;
  if (auto e = coverage.Validate(); !e.empty()) return "coverage." + e;
  if (!(min_coverage >= 0 && min_coverage <= 1)) {
    return "min_coverage=" + Fmt(min_coverage) + " must be in [0, 1]";
  }
  if (!(accelerometer_norm_g > 0)) {
    return "accelerometer_norm_g=" + Fmt(accelerometer_norm_g) + " must be > 0";
  }
  if (!(magnetometer_norm_uT >= 0)) {
    return "magnetometer_norm_uT=" + Fmt(magnetometer_norm_uT) + " must be >= 0";
  }
  if (!(gyro_min_rate_dps > 0)) {
    return "gyro_min_rate_dps=" + Fmt(gyro_min_rate_dps) + " must be > 0";
  }
  return "";
}

MargCalibrationResult CalibrateMarg(const dataset::MargRecording& plane_rotation,
                                    const dataset::MargRecording& free_rotation,
                                    const MargCalibrationOptions& options) {
  if (const std::string err = options.Validate(); !err.empty()) {
    throw std::invalid_argument("MargCalibrationOptions: " + err);
  }
  MargCalibrationResult result;
  const bool inertial = plane_rotation.has_inertial && free_rotation.has_inertial;
  if (plane_rotation.has_inertial != free_rotation.has_inertial) {
    result.warnings.push_back(
        "plane_rotation and free_rotation differ in columns: calibrating the magnetometer only");
  }
  std::ostringstream summary;
  auto run = [&](Sensor sensor, Getter get, double norm) -> bool {
    SensorCalibration cal;
    const std::string err =
        CalibrateVectorSensor(Column(free_rotation, get), Column(plane_rotation, get), norm,
                              options, &cal, &result.missing_directions);
    if (!err.empty()) {
      result.message = std::string(ToString(sensor)) + ": " + err;
      return false;
    }
    summary << ToString(sensor) << ": ellipsoid RMS " << Fmt(cal.ellipsoid_rms_residual)
            << ", inliers " << cal.ellipsoid_inliers << "/" << cal.ellipsoid_samples
            << ", coverage " << Fmt(cal.coverage) << ", alignment roll "
            << Fmt(cal.alignment_roll_deg) << " deg pitch " << Fmt(cal.alignment_pitch_deg)
            << " deg; ";
    if (sensor == Sensor::kAccelerometer) result.calibration.accelerometer = cal;
    if (sensor == Sensor::kMagnetometer) result.calibration.magnetometer = cal;
    return true;
  };
  if (!run(Sensor::kMagnetometer, &Mag, options.magnetometer_norm_uT)) return result;
  if (inertial) {
    if (!run(Sensor::kAccelerometer, &Accel, options.accelerometer_norm_g)) return result;
    if (options.calibrate_gyroscope) {
      SensorCalibration gyro;
      std::vector<double> gx, gy, gz;
      for (const auto& s : free_rotation.samples) {
        gx.push_back(s.gx_dps);
        gy.push_back(s.gy_dps);
        gz.push_back(s.gz_dps);
      }
      gyro.offset = Eigen::Vector3d(MedianOf(gx), MedianOf(gy), MedianOf(gz));
      Eigen::Vector3d axis = Eigen::Vector3d::Zero();
      int used = 0;
      for (const auto& s : plane_rotation.samples) {
        const Eigen::Vector3d w = Gyro(s) - gyro.offset;
        if (w.norm() < options.gyro_min_rate_dps) continue;
        axis += w.z() >= 0 ? w : Eigen::Vector3d(-w);
        ++used;
      }
      if (used >= options.plane.min_samples && axis.norm() > 0) {
        double roll = 0, pitch = 0;
        AlignmentAngles(axis.normalized(), &roll, &pitch);
        gyro.alignment = AlignmentMatrix(roll, pitch);
        gyro.alignment_roll_deg = roll * common::kDegPerRad;
        gyro.alignment_pitch_deg = pitch * common::kDegPerRad;
      } else {
        result.warnings.push_back("gyroscope: only " + std::to_string(used) +
                                  " plane_rotation samples turn faster than " +
                                  Fmt(options.gyro_min_rate_dps) +
                                  " dps: gyroscope not aligned (identity)");
      }
      summary << "gyroscope: offset " << Fmt(gyro.offset.x()) << " " << Fmt(gyro.offset.y()) << " "
              << Fmt(gyro.offset.z()) << " dps";
      result.calibration.gyroscope = gyro;
    }
  }
  result.ok = true;
  result.message = summary.str();
  return result;
}

dataset::MargRecording ApplyCalibration(const MargCalibration& calibration,
                                        const dataset::MargRecording& recording, Stage stage) {
  dataset::MargRecording out = recording;
  for (auto& s : out.samples) {
    if (calibration.magnetometer)
      Set(&s, Sensor::kMagnetometer, calibration.magnetometer->Apply(Mag(s), stage));
    if (!recording.has_inertial) continue;
    if (calibration.accelerometer) {
      Set(&s, Sensor::kAccelerometer, calibration.accelerometer->Apply(Accel(s), stage));
    }
    if (calibration.gyroscope)
      Set(&s, Sensor::kGyroscope, calibration.gyroscope->Apply(Gyro(s), stage));
  }
  return out;
}

std::vector<AttitudeRow> SolveAttitudeSeries(const dataset::MargRecording& recording,
                                             std::optional<double> field_elevation_rad) {
  if (!recording.has_inertial) {
    throw std::invalid_argument(
        "attitude needs accelerometer and magnetometer columns; the recording is "
        "magnetometer-only");
  }
  const auto acc = Column(recording, &Accel);
  const auto mag = Column(recording, &Mag);
  const double elevation =
      field_elevation_rad ? *field_elevation_rad : EstimateFieldElevation(acc, mag);
  const AttitudeReference ref = AttitudeReference::FromElevation(elevation);
  std::vector<AttitudeRow> rows;
  rows.reserve(acc.size());
  std::optional<Eigen::Quaterniond> previous;
  for (size_t i = 0; i < acc.size(); ++i) {
    const AttitudeSolution sol = SolveAttitude(acc[i], mag[i], ref, previous);
    AttitudeRow row;
    row.t_s = recording.samples[i].t_s;
    if (sol.valid) {
      const Eigen::Vector3d rpy = RollPitchYaw(sol.earth_from_body) * common::kDegPerRad;
      row.roll_deg = rpy(0);
      row.pitch_deg = rpy(1);
      row.yaw_deg = rpy(2);
      row.cost = sol.cost;
      previous = sol.earth_from_body;
    } else {
      row.roll_deg = row.pitch_deg = row.yaw_deg = row.cost = std::nan("");
    }
    rows.push_back(row);
  }
  return rows;
}

double MeanCost(const std::vector<AttitudeRow>& rows) {
  double sum = 0;
  int n = 0;
  for (const auto& r : rows) {
    if (std::isfinite(r.cost)) {
      sum += r.cost;
      ++n;
    }
  }
  return n ? sum / n : std::nan("");
}

DirectionError CompareDirections(const std::vector<Eigen::Vector3d>& measured,
                                 const std::vector<Eigen::Vector3d>& truth, bool remove_yaw) {
  if (measured.size() != truth.size()) {
    throw std::invalid_argument("CompareDirections: " + std::to_string(measured.size()) +
                                " measured vs " + std::to_string(truth.size()) + " true vectors");
  }
  DirectionError err;
  double yaw = 0;
  if (remove_yaw) {
    double c = 0, s = 0;
    for (size_t i = 0; i < measured.size(); ++i) {
      const Eigen::Vector3d m = measured[i].normalized(), t = truth[i].normalized();
      c += t.x() * m.x() + t.y() * m.y();
      s += t.y() * m.x() - t.x() * m.y();
    }
    yaw = std::atan2(s, c);
  }
  const Eigen::Matrix3d rz = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  double sum = 0;
  for (size_t i = 0; i < measured.size(); ++i) {
    const Eigen::Vector3d m = rz * measured[i].normalized();
    const double a =
        std::atan2(m.cross(truth[i].normalized()).norm(), m.dot(truth[i].normalized()));
    sum += a * a;
    err.max_deg = std::max(err.max_deg, a * common::kDegPerRad);
  }
  err.rms_deg = measured.empty() ? 0 : std::sqrt(sum / measured.size()) * common::kDegPerRad;
  err.yaw_removed_deg = yaw * common::kDegPerRad;
  return err;
}

}  // namespace msmcal::marg

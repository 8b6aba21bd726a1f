// `msmcal marg ...`: magnetometer / MARG calibration (MARG paper) on an interchange folder's
// marg/ recordings, applying it to CSV files, attitude, capture coverage; and
// `msmcal experiment marg-table1`: MARG Table 1 on the simulated board.
//
// results/marg_calibration.yaml (format msmcal-marg-calibration/1), per sensor:
//   calibrated = alignment * compensation * (raw - offset)
// with offset [3], compensation [3x3], alignment [3x3] (rows), plus figures.
#include <CLI/CLI.hpp>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "app/command_registry.h"
#include "common/units.h"
#include "mocks/marg/marg_simulator.h"
#include "processing/marg/attitude.h"
#include "processing/marg/coverage.h"
#include "processing/marg/marg_calibration.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/results/marg_calibration_yaml.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;
using interchange::FormatDouble;
using results::MargCalibrationFile;
using results::MargValidationFigures;

// ---- shared steps --------------------------------------------------------------------------

double NormRelativeStd(const dataset::MargRecording& rec) {
  double mean = 0, var = 0;
  for (const auto& s : rec.samples) mean += marg::Mag(s).norm();
  mean /= std::max<size_t>(1, rec.samples.size());
  for (const auto& s : rec.samples) var += std::pow(marg::Mag(s).norm() - mean, 2);
  var /= std::max<size_t>(1, rec.samples.size());
  return mean > 0 ? std::sqrt(var) / mean : 0;
}

MargValidationFigures Validate(const marg::MargCalibration& cal,
                               const dataset::MargRecording& val) {
  MargValidationFigures f;
  f.present = true;
  const marg::Stage stages[] = {marg::Stage::kRaw, marg::Stage::kCompensated,
                                marg::Stage::kAlignedCompensated};
  for (int i = 0; i < 3; ++i) {
    const auto rec = marg::ApplyCalibration(cal, val, stages[i]);
    f.cost[i] = val.has_inertial ? marg::MeanCost(marg::SolveAttitudeSeries(rec)) : std::nan("");
    if (i == 2) f.mag_norm_relative_std = NormRelativeStd(rec);
  }
  return f;
}

std::optional<double> FieldElevationDeg(const marg::MargCalibration& cal,
                                        const dataset::MargRecording& free_rotation) {
  if (!free_rotation.has_inertial || !cal.accelerometer || !cal.magnetometer) return std::nullopt;
  const auto rec = marg::ApplyCalibration(cal, free_rotation);
  std::vector<Eigen::Vector3d> a, m;
  for (const auto& s : rec.samples) {
    a.push_back(marg::Accel(s));
    m.push_back(marg::Mag(s));
  }
  return marg::EstimateFieldElevation(a, m) * common::kDegPerRad;
}

std::string MissingHint(const std::vector<Eigen::Vector3d>& missing) {
  std::ostringstream os;
  if (missing.empty()) return "";
  os << "\norientations still missing (field/gravity direction in the sensor frame):";
  const size_t shown = std::min<size_t>(missing.size(), 12);
  for (size_t i = 0; i < shown; ++i) os << "\n  " << marg::DescribeDirection(missing[i]);
  if (missing.size() > shown) os << "\n  ... and " << missing.size() - shown << " more";
  return os.str();
}

marg::MargCalibrationResult CalibrateOrThrow(const dataset::MargRecording& plane,
                                             const dataset::MargRecording& free,
                                             const marg::MargCalibrationOptions& options) {
  marg::MargCalibrationResult res = marg::CalibrateMarg(plane, free, options);
  for (const auto& w : res.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (!res.ok) {
    throw std::runtime_error("marg calibration failed: " + res.message +
                             MissingHint(res.missing_directions));
  }
  return res;
}

void PrintSensorSummary(const marg::MargCalibration& cal) {
  const std::pair<const char*, const std::optional<marg::SensorCalibration>*> sensors[] = {
      {"accelerometer", &cal.accelerometer}, {"magnetometer", &cal.magnetometer}};
  for (const auto& [name, c] : sensors) {
    if (!c->has_value()) continue;
    const auto& s = **c;
    std::printf(
        "%-13s offset [%.4g %.4g %.4g]  semi-axes [%.4g %.4g %.4g]  fit RMS %.2e  inliers %d/%d  "
        "coverage %.2f  alignment roll %.3f pitch %.3f deg\n",
        name, s.offset.x(), s.offset.y(), s.offset.z(), s.ellipsoid.semi_axes.x(),
        s.ellipsoid.semi_axes.y(), s.ellipsoid.semi_axes.z(), s.ellipsoid_rms_residual,
        s.ellipsoid_inliers, s.ellipsoid_samples, s.coverage, s.alignment_roll_deg,
        s.alignment_pitch_deg);
  }
}

void PrintTable1(const MargValidationFigures& f) {
  std::printf("MARG Table 1 (mean Gauss-Newton cost F(x) on the validation recording)\n");
  std::printf("  %-26s %.4e\n", "raw data", f.cost[0]);
  std::printf("  %-26s %.4e\n", "compensated data", f.cost[1]);
  std::printf("  %-26s %.4e\n", "aligned-compensated data", f.cost[2]);
  std::printf("  raw / aligned-compensated = %.1f\n", f.cost[0] / f.cost[2]);
}

// ---- commands ------------------------------------------------------------------------------

struct CalibrateArgs {
  std::string dir;
  double min_coverage = 0.5;
  double mag_norm_uT = 0;
};

void RunCalibrate(const CalibrateArgs& args) {
  const fs::path dir(args.dir);
  const auto plane = interchange::ReadMargCsv(dir / "marg" / "plane_rotation.csv");
  const auto free = interchange::ReadMargCsv(dir / "marg" / "free_rotation.csv");
  marg::MargCalibrationOptions options;
  options.min_coverage = args.min_coverage;
  options.magnetometer_norm_uT = args.mag_norm_uT;
  if (const auto err = options.Validate(); !err.empty())
    throw std::runtime_error("options: " + err);
  const auto res = CalibrateOrThrow(plane, free, options);
  MargCalibrationFile file{res.calibration, FieldElevationDeg(res.calibration, free)};
  MargValidationFigures val;
  if (fs::exists(dir / "marg" / "validation.csv")) {
    val = Validate(res.calibration, interchange::ReadMargCsv(dir / "marg" / "validation.csv"));
  }
  const fs::path out = dir / "results" / "marg_calibration.yaml";
  interchange::WriteFileAtomically(out, results::FormatMargCalibrationYaml(file, val));
  PrintSensorSummary(res.calibration);
  if (val.present && std::isfinite(val.cost[0])) PrintTable1(val);
  std::printf("wrote %s\n", out.string().c_str());
}

void RunApply(const std::string& cal_file, const std::string& in, const std::string& out,
              const std::string& stage_name) {
  const MargCalibrationFile cal = results::ReadMargCalibrationYaml(cal_file);
  marg::Stage stage = marg::Stage::kAlignedCompensated;
  if (stage_name == "raw") stage = marg::Stage::kRaw;
  if (stage_name == "compensated") stage = marg::Stage::kCompensated;
  const auto rec = interchange::ReadMargCsv(in);
  interchange::WriteMargCsv(out, marg::ApplyCalibration(cal.calibration, rec, stage));
}

void RunAttitude(const std::string& cal_file, const std::string& in, const std::string& out,
                 const std::string& input_kind) {
  const MargCalibrationFile cal = results::ReadMargCalibrationYaml(cal_file);
  auto rec = interchange::ReadMargCsv(in);
  if (!rec.has_inertial) {
    throw std::runtime_error(in + ": attitude needs the accelerometer columns (" +
                             "t_s,ax_g,ay_g,az_g,gx_dps,gy_dps,gz_dps,mx_uT,my_uT,mz_uT)");
  }
  if (input_kind == "raw") rec = marg::ApplyCalibration(cal.calibration, rec);
  std::optional<double> elevation;
  if (cal.field_elevation_deg) elevation = *cal.field_elevation_deg / common::kDegPerRad;
  const auto rows = marg::SolveAttitudeSeries(rec, elevation);
  std::string text = "t_s,roll_deg,pitch_deg,yaw_deg,cost\n";
  for (const auto& r : rows) {
    text += FormatDouble(r.t_s) + "," + FormatDouble(r.roll_deg) + "," + FormatDouble(r.pitch_deg) +
            "," + FormatDouble(r.yaw_deg) + "," + FormatDouble(r.cost) + "\n";
  }
  interchange::WriteFileAtomically(out, text);
  std::printf("%zu rows, mean cost %.4e\n", rows.size(), marg::MeanCost(rows));
}

void RunCoverage(const std::string& in, const std::string& sensor, int cells) {
  const auto rec = interchange::ReadMargCsv(in);
  if (sensor == "accel" && !rec.has_inertial)
    throw std::runtime_error(in + ": no accelerometer columns");
  std::vector<Eigen::Vector3d> v;
  for (const auto& s : rec.samples) v.push_back(sensor == "accel" ? marg::Accel(s) : marg::Mag(s));
  // Directions about the fitted centre when a fit is possible, else about the mean.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : v) centre += p / static_cast<double>(std::max<size_t>(1, v.size()));
  Eigen::Matrix3d map = Eigen::Matrix3d::Identity();
  const auto fit = marg::FitEllipsoid(v);
  if (fit.ok()) {
    centre = fit.ellipsoid.centre;
    map = fit.ellipsoid.UnitSphereMap();
  } else {
    std::printf("ellipsoid: %s\n", fit.message.c_str());
  }
  std::vector<Eigen::Vector3d> dirs;
  for (const auto& p : v) dirs.push_back(map * (p - centre));
  marg::CoverageOptions o;
  o.num_cells = cells;
  const auto cov = marg::SphereCoverage(dirs, o);
  std::printf("coverage %.3f (%d/%d cells)%s\n", cov.fraction, cov.covered_cells, cells,
              MissingHint(cov.missing_directions).c_str());
}

struct Table1Args {
  uint64_t seed = 1;
  std::string out;
  bool magnetometer_only = false;
  double outlier_fraction = 0;
};

void RunTable1(const Table1Args& args) {
  sim::MargSimConfig cfg;
  cfg.magnetometer_only = args.magnetometer_only;
  cfg.outlier_fraction = args.outlier_fraction;
  const auto sim = sim::SimulateMarg(cfg, args.seed);
  const auto res = CalibrateOrThrow(sim.plane_rotation, sim.free_rotation, {});
  const MargValidationFigures val = Validate(res.calibration, sim.validation);
  if (!args.out.empty()) {
    const fs::path dir(args.out);
    interchange::WriteMargCsv(dir / "marg" / "plane_rotation.csv", sim.plane_rotation);
    interchange::WriteMargCsv(dir / "marg" / "free_rotation.csv", sim.free_rotation);
    interchange::WriteMargCsv(dir / "marg" / "validation.csv", sim.validation);
    sim::WriteMargTruth(dir, sim.truth);
    MargCalibrationFile file{res.calibration,
                             FieldElevationDeg(res.calibration, sim.free_rotation)};
    interchange::WriteFileAtomically(dir / "results" / "marg_calibration.yaml",
                                     results::FormatMargCalibrationYaml(file, val));
  }
  std::printf(
      "simulated MARG board, seed %llu: %zu plane-rotation, %zu free-rotation, %zu "
      "validation samples\n",
      static_cast<unsigned long long>(args.seed), sim.plane_rotation.samples.size(),
      sim.free_rotation.samples.size(), sim.validation.samples.size());
  PrintSensorSummary(res.calibration);
  if (!args.magnetometer_only) PrintTable1(val);

  // Direction accuracy against truth (yaw about z removed: not observable by the plane method).
  const auto cal = marg::ApplyCalibration(res.calibration, sim.validation);
  std::vector<Eigen::Vector3d> acc, mag, mag_raw;
  for (size_t i = 0; i < cal.samples.size(); ++i) {
    acc.push_back(marg::Accel(cal.samples[i]));
    mag.push_back(marg::Mag(cal.samples[i]));
    mag_raw.push_back(marg::Mag(sim.validation.samples[i]));
  }
  const auto b_true = sim.truth.FieldInBoard(sim.truth.validation);
  const double mag_floor =
      std::sqrt(2.0) * cfg.magnetometer.noise_std / cfg.field_uT * common::kDegPerRad;
  const auto mag_err = marg::CompareDirections(mag, b_true, true);
  std::printf("direction RMS error on validation (yaw removed), noise floor sqrt(2) sigma/|v|:\n");
  std::printf(
      "  magnetometer   raw %.3f deg -> calibrated %.3f deg (floor %.3f deg, yaw %.2f deg)\n",
      marg::CompareDirections(mag_raw, b_true, true).rms_deg, mag_err.rms_deg, mag_floor,
      mag_err.yaw_removed_deg);
  if (!args.magnetometer_only) {
    const auto g_true = sim.truth.GravityInBoard(sim.truth.validation);
    const double acc_floor =
        std::sqrt(2.0) * cfg.accelerometer.noise_std / cfg.gravity_g * common::kDegPerRad;
    std::vector<Eigen::Vector3d> acc_raw;
    for (const auto& s : sim.validation.samples) acc_raw.push_back(marg::Accel(s));
    const auto acc_err = marg::CompareDirections(acc, g_true, true);
    std::printf(
        "  accelerometer  raw %.3f deg -> calibrated %.3f deg (floor %.3f deg, yaw %.2f deg)\n",
        marg::CompareDirections(acc_raw, g_true, true).rms_deg, acc_err.rms_deg, acc_floor,
        acc_err.yaw_removed_deg);
  }
  std::printf("magnetometer norm relative std on validation: %.3f %%\n",
              100 * val.mag_norm_relative_std);
  if (!args.out.empty()) std::printf("wrote %s\n", args.out.c_str());
}

void AddMargCommands(CLI::App& app) {
  auto* marg = GetOrAddSubcommand(app, "marg", "Magnetometer / MARG calibration (MARG paper)");

  auto calibrate_args = std::make_shared<CalibrateArgs>();
  auto* cal = marg->add_subcommand(
      "calibrate", "Calibrate from DIR/marg/*.csv; writes DIR/results/marg_calibration.yaml");
  cal->add_option("DIR", calibrate_args->dir, "interchange folder")->required();
  cal->add_option("--min-coverage", calibrate_args->min_coverage,
                  "fail below this sphere coverage of free_rotation (0..1)");
  cal->add_option("--mag-norm-uT", calibrate_args->mag_norm_uT,
                  "radius of the compensated magnetometer sphere (0: fitted mean radius)");
  cal->callback([calibrate_args] { RunCalibrate(*calibrate_args); });

  auto apply_args = std::make_shared<std::array<std::string, 4>>();
  (*apply_args)[3] = "aligned_compensated";
  auto* apply = marg->add_subcommand("apply", "Write calibrated samples (same columns and rows)");
  apply->add_option("CALIBRATION", (*apply_args)[0], "marg_calibration.yaml")->required();
  apply->add_option("IN", (*apply_args)[1], "input CSV")->required();
  apply->add_option("OUT", (*apply_args)[2], "output CSV")->required();
  apply->add_option("--stage", (*apply_args)[3], "raw|compensated|aligned_compensated")
      ->check(CLI::IsMember({"raw", "compensated", "aligned_compensated"}));
  apply->callback([apply_args] {
    RunApply((*apply_args)[0], (*apply_args)[1], (*apply_args)[2], (*apply_args)[3]);
  });

  auto att_args = std::make_shared<std::array<std::string, 4>>();
  (*att_args)[3] = "raw";
  auto* att = marg->add_subcommand(
      "attitude", "Gauss-Newton attitude per sample: t_s,roll_deg,pitch_deg,yaw_deg,cost");
  att->add_option("CALIBRATION", (*att_args)[0], "marg_calibration.yaml")->required();
  att->add_option("IN", (*att_args)[1], "input CSV (raw samples unless --input calibrated)")
      ->required();
  att->add_option("OUT", (*att_args)[2], "output CSV")->required();
  att->add_option("--input", (*att_args)[3], "raw (apply the calibration first) | calibrated")
      ->check(CLI::IsMember({"raw", "calibrated"}));
  att->callback(
      [att_args] { RunAttitude((*att_args)[0], (*att_args)[1], (*att_args)[2], (*att_args)[3]); });

  auto cov_in = std::make_shared<std::string>();
  auto cov_sensor = std::make_shared<std::string>("mag");
  auto cov_cells = std::make_shared<int>(100);
  auto* cov = marg->add_subcommand(
      "coverage", "Sphere coverage of a free-rotation CSV and the orientations still missing");
  cov->add_option("IN", *cov_in, "CSV")->required();
  cov->add_option("--sensor", *cov_sensor, "mag|accel")->check(CLI::IsMember({"mag", "accel"}));
  cov->add_option("--cells", *cov_cells, "number of sphere cells")->check(CLI::Range(2, 10000));
  cov->callback([=] { RunCoverage(*cov_in, *cov_sensor, *cov_cells); });

  auto* experiment =
      GetOrAddSubcommand(app, "experiment", "Reproduce the papers' tables on simulated data");
  auto t1 = std::make_shared<Table1Args>();
  auto* table1 = experiment->add_subcommand(
      "marg-table1", "MARG Table 1 on the simulated MARG board: simulate, calibrate, validate");
  table1->add_option("--seed", t1->seed, "simulation seed");
  table1->add_option("--out", t1->out,
                     "also write the interchange marg/, truth/ and results/ here");
  table1->add_flag("--magnetometer-only", t1->magnetometer_only,
                   "simulate the Hall sensor variant");
  table1->add_option("--outlier-fraction", t1->outlier_fraction,
                     "fraction of free-rotation magnetometer samples replaced by spikes");
  table1->callback([t1] { RunTable1(*t1); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/80, AddMargCommands);

}  // namespace msmcal::app

// End-to-end: simulated MARG board with known distortions -> calibration -> accuracy on the
// validation recording against the simulator's truth.
#include "mocks/marg/marg_simulator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "common/units.h"
#include "processing/marg/marg_calibration.h"

namespace msmcal {
namespace {

using marg::Stage;

std::vector<Eigen::Vector3d> Col(const dataset::MargRecording& r,
                                 Eigen::Vector3d (*get)(const dataset::MargSample&)) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& s : r.samples) out.push_back(get(s));
  return out;
}

double NormRelativeStd(const std::vector<Eigen::Vector3d>& v) {
  double mean = 0, var = 0;
  for (const auto& x : v) mean += x.norm();
  mean /= v.size();
  for (const auto& x : v) var += std::pow(x.norm() - mean, 2);
  return std::sqrt(var / v.size()) / mean;
}

TEST(MargSimulatorTest, DeterministicInTheSeedAndValidated) {
  sim::MargSimConfig cfg;
  cfg.free_orientations = 20;
  const auto a = sim::SimulateMarg(cfg, 7), b = sim::SimulateMarg(cfg, 7),
             c = sim::SimulateMarg(cfg, 8);
  ASSERT_EQ(a.free_rotation.samples.size(), 80u);
  EXPECT_EQ(a.free_rotation.samples[5].mx_uT, b.free_rotation.samples[5].mx_uT);
  EXPECT_NE(a.free_rotation.samples[5].mx_uT, c.free_rotation.samples[5].mx_uT);
  EXPECT_EQ(a.plane_rotation.samples.size(), a.truth.plane_rotation.earth_from_board.size());
  // Noise-free samples follow the stated model exactly.
  cfg.accelerometer.noise_std = cfg.magnetometer.noise_std = cfg.gyroscope.noise_std = 0;
  const auto n = sim::SimulateMarg(cfg, 1);
  const auto g = n.truth.GravityInBoard(n.truth.validation);
  EXPECT_LT((marg::Accel(n.validation.samples[3]) - cfg.accelerometer.Distort(g[3])).norm(), 1e-12);
  cfg.field_uT = -1;
  EXPECT_THROW(sim::SimulateMarg(cfg, 1), std::invalid_argument);
  EXPECT_NE(cfg.Validate().find("field_uT=-1"), std::string::npos);
}

TEST(MargSimulatorTest, WritesTruthYaml) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("msmcal_marg_truth_" + std::to_string(::getpid()));
  sim::MargSimConfig cfg;
  cfg.free_orientations = 5;
  sim::WriteMargTruth(dir, sim::SimulateMarg(cfg, 3).truth);
  std::ifstream f(dir / "truth" / "marg.yaml");
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("magnetometer:"), std::string::npos);
  EXPECT_NE(text.find("earth_from_board_wxyz"), std::string::npos);
  std::filesystem::remove_all(dir);
}

// The accuracy figures of docs/marg.md.
TEST(MargCalibrationEndToEnd, ReachesNoiseFloorOnValidation) {
  const sim::MargSimConfig cfg;
  const auto sim = sim::SimulateMarg(cfg, 42);
  const auto res = marg::CalibrateMarg(sim.plane_rotation, sim.free_rotation);
  ASSERT_TRUE(res.ok) << res.message;
  ASSERT_TRUE(res.calibration.accelerometer && res.calibration.magnetometer &&
              res.calibration.gyroscope);
  const auto& cal = res.calibration;
  EXPECT_GT(cal.magnetometer->coverage, 0.9);

  const auto calibrated = marg::ApplyCalibration(cal, sim.validation);
  ASSERT_EQ(calibrated.samples.size(), sim.validation.samples.size());
  const auto acc = Col(calibrated, &marg::Accel);
  const auto mag = Col(calibrated, &marg::Mag);
  const auto g_true = sim.truth.GravityInBoard(sim.truth.validation);
  const auto b_true = sim.truth.FieldInBoard(sim.truth.validation);
  // Noise floor of a direction: sqrt(2) sigma / |v| (two tangential components).
  const double acc_floor =
      common::RadToDeg(std::sqrt(2.0) * cfg.accelerometer.noise_std / cfg.gravity_g);
  const double mag_floor =
      common::RadToDeg(std::sqrt(2.0) * cfg.magnetometer.noise_std / cfg.field_uT);
  const auto acc_err = marg::CompareDirections(acc, g_true, /*remove_yaw=*/true);
  const auto mag_err = marg::CompareDirections(mag, b_true, /*remove_yaw=*/true);
  std::printf("accelerometer direction RMS %.3f deg (floor %.3f), yaw %.2f deg\n", acc_err.rms_deg,
              acc_floor, acc_err.yaw_removed_deg);
  std::printf("magnetometer direction RMS %.3f deg (floor %.3f), yaw %.2f deg\n", mag_err.rms_deg,
              mag_floor, mag_err.yaw_removed_deg);
  EXPECT_LT(acc_err.rms_deg, 1.25 * acc_floor);
  EXPECT_LT(mag_err.rms_deg, 1.25 * mag_floor);
  // Raw data are far off.
  EXPECT_GT(marg::CompareDirections(Col(sim.validation, &marg::Mag), b_true, true).rms_deg,
            20 * mag_floor);
  // Magnetometer norm varies by under 1 %; the accelerometer's is 1 g.
  const double mag_norm_std = NormRelativeStd(mag);
  std::printf("magnetometer norm relative std %.4f\n", mag_norm_std);
  EXPECT_LT(mag_norm_std, 0.01);
  double acc_mean = 0;
  for (const auto& a : acc) acc_mean += a.norm() / acc.size();
  EXPECT_NEAR(acc_mean, 1.0, 0.002);
  // Gyroscope: bias removed.
  EXPECT_LT((cal.gyroscope->offset - cfg.gyroscope.offset).norm(), 0.02);

  // MARG Table 1: mean Gauss-Newton cost drops by more than an order of magnitude.
  const double raw = marg::MeanCost(marg::SolveAttitudeSeries(sim.validation));
  const double comp = marg::MeanCost(
      marg::SolveAttitudeSeries(marg::ApplyCalibration(cal, sim.validation, Stage::kCompensated)));
  const double aligned = marg::MeanCost(marg::SolveAttitudeSeries(calibrated));
  std::printf("Table 1: raw %.3e compensated %.3e aligned-compensated %.3e\n", raw, comp, aligned);
  EXPECT_GT(raw, 10 * aligned);
  EXPECT_LT(aligned, comp);
}

class MagOnlyOutliers : public ::testing::TestWithParam<double> {};

TEST_P(MagOnlyOutliers, CalibratesTheHallVariantDespiteSpikes) {
  sim::MargSimConfig cfg;
  cfg.magnetometer_only = true;
  cfg.outlier_fraction = GetParam();
  const auto sim = sim::SimulateMarg(cfg, 5);
  EXPECT_FALSE(sim.free_rotation.has_inertial);
  const auto res = marg::CalibrateMarg(sim.plane_rotation, sim.free_rotation);
  ASSERT_TRUE(res.ok) << res.message;
  EXPECT_FALSE(res.calibration.accelerometer.has_value());
  EXPECT_TRUE(res.calibration.magnetometer.has_value());
  const auto mag = Col(marg::ApplyCalibration(res.calibration, sim.validation), &marg::Mag);
  const auto b_true = sim.truth.FieldInBoard(sim.truth.validation);
  const double mag_floor =
      common::RadToDeg(std::sqrt(2.0) * cfg.magnetometer.noise_std / cfg.field_uT);
  EXPECT_LT(marg::CompareDirections(mag, b_true, true).rms_deg, 1.25 * mag_floor);
  EXPECT_LT(NormRelativeStd(mag), 0.01);
  EXPECT_THROW(marg::SolveAttitudeSeries(sim.validation), std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(MargCalibrationEndToEnd, MagOnlyOutliers,
                         ::testing::Values(0.0, 0.05, 0.2));

TEST(MargCalibrationEndToEnd, ReportsPoorCoverageWithMissingDirections) {
  sim::MargSimConfig cfg;
  cfg.magnetometer_only = true;
  auto sim = sim::SimulateMarg(cfg, 9);
  // Keep only orientations where the field points into one half of the sensor's frame.
  dataset::MargRecording half;
  half.has_inertial = false;
  for (size_t i = 0; i < sim.free_rotation.samples.size(); ++i) {
    if (sim.truth.FieldInBoard(sim.truth.free_rotation)[i].z() > 0) {
      half.samples.push_back(sim.free_rotation.samples[i]);
    }
  }
  marg::MargCalibrationOptions opt;
  opt.min_coverage = 0.8;
  const auto res = marg::CalibrateMarg(sim.plane_rotation, half, opt);
  EXPECT_FALSE(res.ok);
  EXPECT_NE(res.message.find("magnetometer"), std::string::npos) << res.message;
  EXPECT_FALSE(res.missing_directions.empty()) << res.message;
}

}  // namespace
}  // namespace msmcal

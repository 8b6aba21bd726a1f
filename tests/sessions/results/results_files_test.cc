#include "sessions/results/results_files.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "sessions/interchange/interchange_io.h"
#include "tests/testing/test_files.h"

namespace msmcal::results {
namespace {

namespace fs = std::filesystem;
using testing::Slurp;
using testing::Spit;
using testing::TempDir;

// The message of what `read` throws (empty when it does not throw InterchangeError).
template <typename Read>
std::string ErrorOf(Read read) {
  try {
    read();
  } catch (const interchange::InterchangeError& e) {
    return e.what();
  }
  return "";
}

TEST(ResultsCsv, MirrorPlanesRoundTripExactlyAndTheBytesAreTheFormat) {
  TempDir dir;
  dataset::MirrorPlaneRow r;
  r.j = 7;
  r.t_s = 0.1;
  r.plane_in_world.n = Eigen::Vector3d(0.6, -0.8, 0);
  r.plane_in_world.d = -123.456;
  r.alpha_deg = 1.0 / 3;
  r.beta_deg = -2e-7;
  r.trans_mm = 0.05;
  r.sigma_alpha_deg = 1e-3;
  r.sigma_beta_deg = 2e-3;
  r.sigma_trans_mm = 3e-3;
  const fs::path file = dir.path() / "mirror_planes.csv";
  WriteMirrorPlanesCsv(file, {r});
  EXPECT_EQ(Slurp(file),
            "j,t_s,nx,ny,nz,d_mm,alpha_deg,beta_deg,trans_mm,sigma_alpha_deg,sigma_beta_deg,"
            "sigma_trans_mm\n7,0.1,0.6,-0.8,0,-123.456,0.3333333333333333,-2e-07,0.05,0.001,0.002,"
            "0.003\n");
  const auto back = ReadMirrorPlanesCsv(file);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].j, 7);
  EXPECT_EQ(back[0].alpha_deg, r.alpha_deg);
  EXPECT_EQ(back[0].plane_in_world.n, r.plane_in_world.n);
  EXPECT_EQ(back[0].plane_in_world.d, r.plane_in_world.d);
  EXPECT_EQ(back[0].sigma_trans_mm, r.sigma_trans_mm);
}

TEST(ResultsCsv, BeamsAndValidationRoundTrip) {
  TempDir dir;
  WriteBeamsCsv(dir.path() / "beams.csv", {{2, {1.5, -2, 3e5}, {0, 0.6, 0.8}}});
  EXPECT_EQ(Slurp(dir.path() / "beams.csv"), "beam,px,py,pz,vx,vy,vz\n2,1.5,-2,3e+05,0,0.6,0.8\n");
  const auto beams = ReadBeamsCsv(dir.path() / "beams.csv");
  ASSERT_EQ(beams.size(), 1u);
  EXPECT_EQ(beams[0].beam, 2);
  EXPECT_EQ(beams[0].p, Eigen::Vector3d(1.5, -2, 3e5));
  EXPECT_EQ(beams[0].v, Eigen::Vector3d(0, 0.6, 0.8));

  WriteValidationCsv(dir.path() / "validation.csv", {{3, 11, 0.25, 1e-4}, {4, 12, 0.5, 2e-4}});
  EXPECT_EQ(Slurp(dir.path() / "validation.csv"),
            "beam,j,err_px,err_deg\n3,11,0.25,1e-04\n4,12,0.5,2e-04\n");
  const auto val = ReadValidationCsv(dir.path() / "validation.csv");
  ASSERT_EQ(val.size(), 2u);
  EXPECT_EQ(val[1].beam, 4);
  EXPECT_EQ(val[1].j, 12);
  EXPECT_EQ(val[1].err_deg, 2e-4);
}

TEST(ResultsCsv, TheTextEntryPointsReadWhatTheFormattersWrite) {
  const std::vector<dataset::BeamRow> beams = {{2, {1.5, -2, 3e5}, {0, 0.6, 0.8}}};
  const std::string text = FormatBeamsCsv(beams);
  EXPECT_EQ(text, "beam,px,py,pz,vx,vy,vz\n2,1.5,-2,3e+05,0,0.6,0.8\n");
  EXPECT_EQ(FormatBeamsCsv(ParseBeamsCsv(text, "beams.csv")), text);
  const std::string val = FormatValidationCsv({{3, 11, 0.25, 1e-4}});
  EXPECT_EQ(FormatValidationCsv(ParseValidationCsv(val, "validation.csv")), val);
  dataset::MirrorPlaneRow r;
  r.j = 7;
  r.t_s = 0.1;
  const std::string planes = FormatMirrorPlanesCsv({r});
  EXPECT_EQ(FormatMirrorPlanesCsv(ParseMirrorPlanesCsv(planes, "mirror_planes.csv")), planes);
  EXPECT_NE(ErrorOf([] {
              ParseBeamsCsv("beam,px\n", "results/beams.csv");
            }).find("results/beams.csv:1: header is"),
            std::string::npos);
}

TEST(ResultsCsv, ValidationDetailRoundTripFromTheSolversRows) {
  TempDir dir;
  solver::ValidationDetail v;
  v.row = {5, 9, 0.125, 0.01};
  v.baseline = {5, 9, 0.75, 0.06};
  v.predicted_sigma_px = 0.1;
  v.normalised_error = 1.25;
  const fs::path file = dir.path() / "validation_detail.csv";
  WriteValidationDetailCsv(file, ValidationDetailRows({v}));
  EXPECT_EQ(Slurp(file),
            "beam,j,err_px,err_deg,baseline_err_px,baseline_err_deg,predicted_sigma_px,"
            "normalised_error\n5,9,0.125,0.01,0.75,0.06,0.1,1.25\n");
  const auto back = ReadValidationDetailCsv(file);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].beam, 5);
  EXPECT_EQ(back[0].j, 9);
  EXPECT_EQ(back[0].baseline_err_px, 0.75);
  EXPECT_EQ(back[0].predicted_sigma_px, 0.1);
  EXPECT_EQ(back[0].normalised_error, 1.25);
}

TEST(ResultsCsv, ValidationDotsRoundTripFromTheSolversRows) {
  TempDir dir;
  solver::ValidationDetail v;
  v.row = {5, 9, 0.125, 0.01};
  v.observed_px = {1200.5, 800.25};
  v.predicted_px = {1200.375, 800.5};
  v.cov_px2 << 0.0625, -0.01, -0.01, 0.03125;
  v.joint_whitened = {0.75, -1.5};
  const fs::path file = dir.path() / "validation_dots.csv";
  WriteValidationDotsCsv(file, ValidationDotRows({v}));
  EXPECT_EQ(Slurp(file),
            "beam,j,observed_x_px,observed_y_px,predicted_x_px,predicted_y_px,cov_xx_px2,"
            "cov_xy_px2,cov_yy_px2,joint_whitened_1,joint_whitened_2\n"
            "5,9,1200.5,800.25,1200.375,800.5,0.0625,-0.01,0.03125,0.75,-1.5\n");
  const auto back = ReadValidationDotsCsv(file);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].beam, 5);
  EXPECT_EQ(back[0].j, 9);
  EXPECT_EQ(back[0].observed_px, v.observed_px);
  EXPECT_EQ(back[0].predicted_px, v.predicted_px);
  EXPECT_EQ(back[0].cov_px2, v.cov_px2);  // symmetric: the off-diagonal written once
  EXPECT_EQ(back[0].joint_whitened, v.joint_whitened);
}

TEST(ResultsCsv, ResidualsRoundTripAndRefuseAnUnknownFamily) {
  TempDir dir;
  const fs::path file = dir.path() / "residuals.csv";
  WriteResidualsCsv(file, {{solver::kCornersC2World, 3, {10.5, 20.25}, {0.5, -1.25}},
                           {solver::kReflectedDots, 7, {1000, 900}, {2, 0.125}}});
  EXPECT_EQ(Slurp(file),
            "family,group,observed_x_px,observed_y_px,whitened_1,whitened_2\n"
            "2,3,10.5,20.25,0.5,-1.25\n4,7,1000,900,2,0.125\n");
  const auto back = ReadResidualsCsv(file);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].family, solver::kReflectedDots);
  EXPECT_EQ(back[1].group, 7);
  EXPECT_EQ(back[1].observed_px, Eigen::Vector2d(1000, 900));
  EXPECT_EQ(back[1].whitened, Eigen::Vector2d(2, 0.125));
  Spit(file, "family,group,observed_x_px,observed_y_px,whitened_1,whitened_2\n9,0,0,0,0,0\n");
  EXPECT_EQ(ErrorOf([&] { ReadResidualsCsv(file); }),
            file.string() + ":2: column 'family': 9 is not a residual family (0..5)");
}

TEST(ResultsCsv, HallPosesRoundTrip) {
  TempDir dir;
  const fs::path file = dir.path() / "hall_poses.csv";
  WriteHallPosesCsv(file, {{1000, 0.001, 1.5, -2.25, 0.01}, {2000.5, 0.002, 1.75, -2.5, 0.02}});
  EXPECT_EQ(Slurp(file),
            "mcu_time_us,t_s,alpha_deg,beta_deg,trans_mm\n1000,0.001,1.5,-2.25,0.01\n"
            "2000.5,0.002,1.75,-2.5,0.02\n");
  const auto back = ReadHallPosesCsv(file);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].mcu_time_us, 2000.5);
  EXPECT_EQ(back[1].beta_deg, -2.5);
}

// The native files' text entry points (used by the results_csv fuzz target): Format*Csv is
// exactly what Write*Csv puts in the file, Parse*Csv reads it back to the same rows, and a
// parse error names the display name given, not a file.
TEST(ResultsCsv, TheNativeFilesTextEntryPointsAreTheFileReadersAndWriters) {
  TempDir dir;
  ValidationDetailRow detail{5, 9, 0.125, 0.01, 0.75, 0.06, 0.1, 1.25};
  WriteValidationDetailCsv(dir.path() / "d.csv", {detail});
  const std::string detail_text = FormatValidationDetailCsv({detail});
  EXPECT_EQ(detail_text, Slurp(dir.path() / "d.csv"));
  const auto detail_back = ParseValidationDetailCsv(detail_text, "results/validation_detail.csv");
  ASSERT_EQ(detail_back.size(), 1u);
  EXPECT_EQ(detail_back[0].normalised_error, 1.25);
  EXPECT_EQ(FormatValidationDetailCsv(detail_back), detail_text);

  ValidationDotRow dot;
  dot.beam = 3;
  dot.j = 17;
  dot.observed_px = {1147.962352788381, 933.0076062857379};
  dot.predicted_px = {1147.9580364044714, 932.8677302205726};
  dot.cov_px2 << 0.027668890737341738, -0.0007961832580364724, -0.0007961832580364724,
      0.02408513295894977;
  dot.joint_whitened = {0.02594921299088467, 0.9025286702972861};
  WriteValidationDotsCsv(dir.path() / "v.csv", {dot, dot});
  const std::string dots_text = FormatValidationDotsCsv({dot, dot});
  EXPECT_EQ(dots_text, Slurp(dir.path() / "v.csv"));
  const auto dots_back = ParseValidationDotsCsv(dots_text, "results/validation_dots.csv");
  ASSERT_EQ(dots_back.size(), 2u);
  EXPECT_EQ(dots_back[1].j, 17);
  EXPECT_EQ(dots_back[1].observed_px, dot.observed_px);  // lossless doubles
  EXPECT_EQ(dots_back[1].cov_px2, dot.cov_px2);
  EXPECT_EQ(dots_back[1].joint_whitened, dot.joint_whitened);
  EXPECT_EQ(FormatValidationDotsCsv(dots_back), dots_text);
  EXPECT_NE(ErrorOf([&] {
              ParseValidationDotsCsv(dots_text.substr(0, dots_text.find('\n') + 1) + "3,1,x\n",
                                     "results/validation_dots.csv");
            }).find("results/validation_dots.csv:2: expected 11 cells"),
            std::string::npos);
  // A bad covariance cell is named like any other (results_csv fuzz finding: it threw inside
  // Eigen's comma initializer, whose destructor then asserted; an abort in the fuzz build).
  EXPECT_EQ(ErrorOf([&] {
              ParseValidationDotsCsv(
                  dots_text.substr(0, dots_text.find('\n') + 1) +
                      "3,0,1147.9,933,1147.9,932.8,0.0276,-0.0007,0.024x,0.02,0.9\n",
                  "results/validation_dots.csv");
            }),
            "results/validation_dots.csv:2: column 'cov_yy_px2': '0.024x' is not a number");

  const std::vector<solver::WhitenedResidual> residuals = {
      {solver::kSlidingDots, 2, {1700.8831930574975, 982.9923919487597}, {-0.147, 1.0625}},
      {solver::kReflectedDotsNearEdge, 11, {3, 4}, {0, -2.5}}};
  WriteResidualsCsv(dir.path() / "r.csv", residuals);
  const std::string residuals_text = FormatResidualsCsv(residuals);
  EXPECT_EQ(residuals_text, Slurp(dir.path() / "r.csv"));
  const auto residuals_back = ParseResidualsCsv(residuals_text, "results/residuals.csv");
  ASSERT_EQ(residuals_back.size(), 2u);
  EXPECT_EQ(residuals_back[1].family, solver::kReflectedDotsNearEdge);
  EXPECT_EQ(residuals_back[1].group, 11);
  EXPECT_EQ(residuals_back[0].observed_px, residuals[0].observed_px);
  EXPECT_EQ(FormatResidualsCsv(residuals_back), residuals_text);
  // The family check names the display name too (it used to be built from the file path).
  EXPECT_EQ(ErrorOf([] {
              ParseResidualsCsv(
                  "family,group,observed_x_px,observed_y_px,whitened_1,whitened_2\n-1,0,0,0,0,0\n",
                  "results/residuals.csv");
            }),
            "results/residuals.csv:2: column 'family': -1 is not a residual family (0..5)");

  const std::vector<HallPoseRow> poses = {{29477000, -0.05571937755286043, 0.0227, -8.01, 0.29}};
  WriteHallPosesCsv(dir.path() / "h.csv", poses);
  const std::string poses_text = FormatHallPosesCsv(poses);
  EXPECT_EQ(poses_text, Slurp(dir.path() / "h.csv"));
  const auto poses_back = ParseHallPosesCsv(poses_text, "results/hall_poses.csv");
  ASSERT_EQ(poses_back.size(), 1u);
  EXPECT_EQ(poses_back[0].t_s, poses[0].t_s);
  EXPECT_EQ(FormatHallPosesCsv(poses_back), poses_text);
  EXPECT_NE(ErrorOf([] {
              ParseHallPosesCsv("mcu_time_us,t_s\n", "results/hall_poses.csv");
            }).find("results/hall_poses.csv:1: header is"),
            std::string::npos);
}

TEST(ResultsCsv, MalformedFilesNameFileLineAndColumn) {
  TempDir dir;
  const fs::path poses = dir.path() / "hall_poses.csv";
  Spit(poses, "mcu_time_us,t_s,alpha_deg,beta_deg,trans_mm\n1,0,0,0,0\n\n2,0,abc,0,0\n");
  EXPECT_EQ(ErrorOf([&] { ReadHallPosesCsv(poses); }),
            poses.string() + ":4: column 'alpha_deg': 'abc' is not a number");
  // A missing column is an error, never a zero.
  const fs::path detail = dir.path() / "validation_detail.csv";
  Spit(detail, "beam,j,err_px,err_deg\n1,2,0.5,0.1\n");
  EXPECT_NE(ErrorOf([&] {
              ReadValidationDetailCsv(detail);
            }).find(detail.string() + ":1: header is 'beam,j,err_px,err_deg' but expected"),
            std::string::npos);
  Spit(detail,
       "beam,j,err_px,err_deg,baseline_err_px,baseline_err_deg,predicted_sigma_px,"
       "normalised_error\n1,2,0.5,0.1,0.2\n");
  EXPECT_NE(ErrorOf([&] {
              ReadValidationDetailCsv(detail);
            }).find(detail.string() + ":2: expected 8 cells"),
            std::string::npos);
  const fs::path planes = dir.path() / "mirror_planes.csv";
  Spit(planes,
       "j,t_s,nx,ny,nz,d_mm,alpha_deg,beta_deg,trans_mm,sigma_alpha_deg,sigma_beta_deg,"
       "sigma_trans_mm\n1.5,0,0,0,1,0,0,0,0,0,0,nan\n");
  EXPECT_EQ(ErrorOf([&] { ReadMirrorPlanesCsv(planes); }),
            planes.string() + ":2: column 'j': '1.5' is not an integer");
  EXPECT_NE(ErrorOf([&] { ReadBeamsCsv(dir.path() / "absent.csv"); }).find("absent.csv"),
            std::string::npos);
}

MirrorPosesSummary SampleSummary() {
  MirrorPosesSummary s;
  s.solve_time_s = 12.5;
  s.ceres_time_s = 0.75;
  s.ceres_iterations = 17;
  s.planes_scan = 40;
  s.planes_fast_only = 2;
  s.planes_neutral = 1;
  s.beams = 3;
  s.mean_spanning_angle_deg = 27.5;
  s.validation_rms_deg = 0.0125;
  s.validation_rms_px = 0.31;
  s.baseline_validation_rms_deg = 0.05;
  s.baseline_validation_rms_px = 1.2;
  s.validation_normalised_rms = std::numeric_limits<double>::quiet_NaN();
  s.validation_count = 80;
  s.corner_variance_factor = 1.1;
  s.dot_variance_factor = 0.9;
  s.variance_factors = {{"corners_c1_world", 1.1, 300.5}, {"reflected_dots", 0.9, 75}};
  s.mirror0_sigma_rotation_deg = {0.01, 0.02, 0.03};
  s.mirror0_sigma_origin_mm = {0.1, 0.2, 0.3};
  s.rms_sigma_alpha_deg = 0.004;
  s.rms_sigma_beta_deg = 0.005;
  s.rms_sigma_trans_mm = 0.006;
  s.beam_direction_sigma_deg = {0.011, 0.012, 0.025};
  s.rms_sigma_normal_world_deg = 0.007;
  s.dropped_frames = {{"step2/0003.png", "world board not found"}};
  s.notes = {"3 beams", "trigger assignment: 40 of 40"};
  s.world_from_mirror0_rotation << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  s.world_from_mirror0_translation = {10, 20, 300};
  return s;
}

TEST(SummaryJson, MirrorPosesRoundTripAndOtherKeysAreKept) {
  TempDir dir;
  const fs::path file = dir.path() / "summary.json";
  Spit(file, "{\"marg\": {\"cost\": 1.5}}\n");
  const MirrorPosesSummary s = SampleSummary();
  WriteMirrorPosesSummary(file, s);
  const std::string text = Slurp(file);
  EXPECT_NE(text.find("\"marg\": {\n    \"cost\": 1.5\n  }"), std::string::npos) << text;
  EXPECT_NE(text.find("\"validation_normalised_rms\": null"), std::string::npos) << text;
  const MirrorPosesSummary b = ReadMirrorPosesSummary(file);
  EXPECT_EQ(b.solve_time_s, s.solve_time_s);
  EXPECT_EQ(b.ceres_iterations, s.ceres_iterations);
  EXPECT_EQ(b.planes_scan, s.planes_scan);
  EXPECT_EQ(b.beams, s.beams);
  EXPECT_EQ(b.validation_rms_deg, s.validation_rms_deg);
  EXPECT_EQ(b.baseline_validation_rms_px, s.baseline_validation_rms_px);
  EXPECT_TRUE(std::isnan(b.validation_normalised_rms));
  EXPECT_EQ(b.validation_count, s.validation_count);
  ASSERT_EQ(b.variance_factors.size(), 2u);
  EXPECT_EQ(b.variance_factors[1].name, "reflected_dots");
  EXPECT_EQ(b.variance_factors[1].redundancy, 75);
  EXPECT_EQ(b.mirror0_sigma_origin_mm, s.mirror0_sigma_origin_mm);
  EXPECT_EQ(b.beam_direction_sigma_deg, s.beam_direction_sigma_deg);
  EXPECT_EQ(b.rms_sigma_normal_world_deg, s.rms_sigma_normal_world_deg);
  ASSERT_EQ(b.dropped_frames.size(), 1u);
  EXPECT_EQ(b.dropped_frames[0].reason, "world board not found");
  EXPECT_EQ(b.notes, s.notes);
  EXPECT_EQ(b.world_from_mirror0_rotation, s.world_from_mirror0_rotation);
  EXPECT_EQ(b.world_from_mirror0_translation, s.world_from_mirror0_translation);
  // Writing what was read gives the same bytes.
  WriteMirrorPosesSummary(file, b);
  EXPECT_EQ(Slurp(file), text);
}

TEST(SummaryJson, AMissingOrMistypedFieldIsNamed) {
  TempDir dir;
  const fs::path file = dir.path() / "summary.json";
  Spit(file, "{\"mirror_poses\": {\"validation_rms_deg\": 0.1}}\n");
  EXPECT_EQ(ErrorOf([&] { ReadMirrorPosesSummary(file); }),
            file.string() + ": mirror_poses.solve_time_s: missing");
  WriteMirrorPosesSummary(file, SampleSummary());
  std::string text = Slurp(file);
  const std::string key = "\"planes_scan\": 40";
  text.replace(text.find(key), key.size(), "\"planes_scan\": \"forty\"");
  Spit(file, text);
  EXPECT_EQ(ErrorOf([&] { ReadMirrorPosesSummary(file); }),
            file.string() + ": mirror_poses.planes_scan: expected an integer, got \"forty\"");
  Spit(file, "{\"other\": 1}\n");
  EXPECT_EQ(ErrorOf([&] { ReadMirrorPosesSummary(file); }),
            file.string() + ": mirror_poses: missing");
}

hall::HallCalibrationResult SampleHallResult() {
  hall::HallCalibrationResult r;
  hall::HallModel& m = r.final_fit.model;
  m.kind = hall::HallModelKind::kLinear;
  m.a = Eigen::MatrixXd::Zero(3, m.FeatureCount());
  for (int i = 0; i < m.a.rows(); ++i)
    for (int j = 0; j < m.a.cols(); ++j) m.a(i, j) = 0.1 * i - 0.01 * j + 1e-9;
  m.delta_t_s = 1.25e-4;
  r.final_fit.train_rms = {0.01, 0.02, 0.003};
  hall::ModelStats stats;
  stats.kind = m.kind;
  stats.test_rms_mean = {0.083, 0.069, 0.1};
  stats.test_rms_std = {0.04, 0.04, 0.08};
  stats.delta_t_mean_s = 1.2e-4;
  r.table = {stats};
  r.best = m.kind;
  r.actual_time_base.offset_us = 12345.5;
  r.actual_time_base.rate_us_per_s = 1e6 * (1 + 3e-6);
  r.actual_time_base.pattern_period_s = 0.5;
  r.foreground.background =
      hall::PhaseProfile::FromBins(0.5, {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {-1, -2, -3.5}});
  return r;
}

TEST(HallModelYaml, RoundTripOfTheFieldsThePredictorAndTheReportUse) {
  TempDir dir;
  const hall::HallCalibrationResult r = SampleHallResult();
  const fs::path file = dir.path() / "hall_model.yaml";
  interchange::WriteFileAtomically(file, FormatHallModelYaml(r, {}));
  const HallModelFile back = ReadHallModelYaml(file);
  EXPECT_EQ(back.model.kind, r.final_fit.model.kind);
  EXPECT_EQ(back.model.delta_t_s, r.final_fit.model.delta_t_s);
  EXPECT_EQ(back.model.a, r.final_fit.model.a);
  EXPECT_EQ(back.time_base.offset_us, r.actual_time_base.offset_us);
  EXPECT_EQ(back.time_base.rate_us_per_s, r.actual_time_base.rate_us_per_s);
  EXPECT_EQ(back.background.bins(), r.foreground.background.bins());
  ASSERT_TRUE(back.test_rms.has_value());
  EXPECT_EQ(*back.test_rms, r.table[0].test_rms_mean);
}

// time_offset (issue 15): the session's dt is written as a figure only when identified; a file
// written before time_offset existed reads without one.
TEST(HallModelYaml, TimeOffsetRoundTripAndOlderFilesWithoutIt) {
  hall::HallCalibrationResult r = SampleHallResult();
  r.delta_t.status = hall::DeltaTStatus::kIdentified;
  r.delta_t.model = hall::HallModelKind::kLinear;
  r.delta_t.delta_t_s = 1.25e-4;
  r.delta_t.sigma_s = 3e-6;
  r.delta_t.separation = 812.5;
  r.delta_t.runner_up_s = -2.3e-3;
  const HallModelFile ok = ParseHallModelYaml(FormatHallModelYaml(r, {}), "a.yaml");
  ASSERT_TRUE(ok.time_offset.has_value());
  EXPECT_TRUE(ok.time_offset->identified());
  EXPECT_EQ(ok.time_offset->delta_t_s, 1.25e-4);
  EXPECT_EQ(ok.time_offset->sigma_s, 3e-6);
  EXPECT_EQ(ok.time_offset->separation, 812.5);
  EXPECT_EQ(ok.time_offset->runner_up_s, -2.3e-3);

  r.delta_t.status = hall::DeltaTStatus::kAmbiguous;
  r.delta_t.reason = "another minimum at -2.300 ms costs only 8.2 residual variances more";
  const std::string text = FormatHallModelYaml(r, {});
  const HallModelFile no = ParseHallModelYaml(text, "b.yaml");
  ASSERT_TRUE(no.time_offset.has_value());
  EXPECT_EQ(no.time_offset->status, hall::DeltaTStatus::kAmbiguous);
  EXPECT_EQ(no.time_offset->reason, r.delta_t.reason);
  EXPECT_TRUE(std::isnan(no.time_offset->delta_t_s));
  EXPECT_EQ(no.model.delta_t_s, r.final_fit.model.delta_t_s);  // the predictor's dt stays
  const YAML::Node y = YAML::Load(text);
  EXPECT_FALSE(y["time_offset"]["identified"].as<bool>());
  EXPECT_FALSE(y["time_offset"]["delta_t_s"]);

  // Before issue 15: no time_offset section.
  YAML::Node old = YAML::Load(text);
  old.remove("time_offset");
  YAML::Emitter e;
  e << old;
  const HallModelFile before = ParseHallModelYaml(e.c_str(), "c.yaml");
  EXPECT_FALSE(before.time_offset.has_value());
  EXPECT_EQ(before.model.delta_t_s, r.final_fit.model.delta_t_s);
  // A status that is not one of ours is named.
  std::string bad = text;
  const size_t at = bad.find("status: ambiguous");
  ASSERT_NE(at, std::string::npos) << text;
  bad.replace(at, 17, "status: maybe");
  EXPECT_NE(ErrorOf([&] {
              ParseHallModelYaml(bad, "d.yaml");
            }).find("d.yaml: field 'time_offset.status': unknown status 'maybe'"),
            std::string::npos);
}

// dt identified by the drives' phases (processing/hall/drive_phase.h): the method and the field
// model's own verdict round-trip; files without `method` are the field model's; an unknown
// method is named.
TEST(HallModelYaml, TheDrivePhasesMethodRoundTrips) {
  hall::HallCalibrationResult r = SampleHallResult();
  r.delta_t.status = hall::DeltaTStatus::kIdentified;
  r.delta_t.method = hall::DeltaTMethod::kDrivePhases;
  r.delta_t.field_status = hall::DeltaTStatus::kSplitsDisagree;
  r.delta_t.field_reason = "13 of 50 train/test splits find dt elsewhere";
  r.delta_t.delta_t_s = 5.55e-4;
  r.delta_t.sigma_s = 1.1e-5;
  r.drive_phase.determined = r.drive_phase.chooses_valley = true;
  r.drive_phase.delta_t_s = 5.55e-4;
  r.drive_phase.separation = 873.5;
  r.bracket = hall::DeltaTBracket::kDrivePhases;
  const std::string text = FormatHallModelYaml(r, {});
  const HallModelFile back = ParseHallModelYaml(text, "a.yaml");
  ASSERT_TRUE(back.time_offset.has_value());
  EXPECT_TRUE(back.time_offset->identified());
  EXPECT_EQ(back.time_offset->method, hall::DeltaTMethod::kDrivePhases);
  EXPECT_EQ(back.time_offset->field_status, hall::DeltaTStatus::kSplitsDisagree);
  EXPECT_EQ(back.time_offset->field_reason, r.delta_t.field_reason);
  EXPECT_EQ(back.time_offset->delta_t_s, 5.55e-4);
  const YAML::Node y = YAML::Load(text);
  EXPECT_EQ(y["time_offset"]["bracket_from"].as<std::string>(), "drive phases");
  EXPECT_TRUE(y["time_offset"]["drive_phase"]["determined"].as<bool>());
  EXPECT_EQ(y["time_offset"]["drive_phase"]["separation"].as<double>(), 873.5);
  // Without `method` (files before the drives' phases): the field model's.
  YAML::Node old = YAML::Load(text);
  old["time_offset"].remove("method");
  YAML::Emitter e;
  e << old;
  EXPECT_EQ(ParseHallModelYaml(e.c_str(), "b.yaml").time_offset->method,
            hall::DeltaTMethod::kFieldModel);
  std::string bad = text;
  const size_t at = bad.find("method: drive phases");
  ASSERT_NE(at, std::string::npos) << text;
  bad.replace(at, 20, "method: guess");
  EXPECT_NE(ErrorOf([&] {
              ParseHallModelYaml(bad, "c.yaml");
            }).find("c.yaml: field 'time_offset.method': unknown method 'guess'"),
            std::string::npos);
}

TEST(HallModelYaml, ABadFieldIsNamed) {
  TempDir dir;
  const fs::path file = dir.path() / "hall_model.yaml";
  std::string text = FormatHallModelYaml(SampleHallResult(), {});
  const size_t at = text.find("delta_t_s: ");
  text.replace(at, text.find('\n', at) - at, "delta_t_s: abc");
  Spit(file, text);
  const std::string e = ErrorOf([&] { ReadHallModelYaml(file); });
  EXPECT_NE(e.find(file.string() + ": field 'delta_t_s': expected a number (line "),
            std::string::npos)
      << e;
}

// Fuzz findings (docs/fuzzing.md): a document or section that is not a mapping, a format or model
// that is not a text and bins that are not a list name the file and the field (yaml-cpp's
// "operator[] call on a scalar" / "bad conversion" escaped without them).
TEST(HallModelYaml, AWrongShapeNamesTheFileAndTheField) {
  const std::string good = FormatHallModelYaml(SampleHallResult(), {});
  EXPECT_NO_THROW(ParseHallModelYaml(good, "hall_model.yaml"));
  const std::string head = "format: msmcal-hall-model/1\nmodel: linear\ndelta_t_s: 0\n";
  std::string bins = good;
  const size_t at = bins.find("bins_uT:");
  ASSERT_NE(at, std::string::npos) << good;
  bins = bins.substr(0, at) + "bins_uT: {a: 1}\n";
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string t = good;
    const size_t p = t.find(from);
    EXPECT_NE(p, std::string::npos) << from;
    return p == std::string::npos ? t : t.replace(p, from.size(), to);
  };
  // The protocol as written: random splits, the options' repetitions (50).
  EXPECT_FALSE(ParseHallModelYaml(good, "m.yaml").leave_one_out);
  EXPECT_EQ(ParseHallModelYaml(good, "m.yaml").repetitions, 50);
  const std::pair<std::string, std::string> cases[] = {
      {replaced("evaluation: random splits", "evaluation: bootstrap"),
       "field 'protocol.evaluation': expected 'random splits' or 'leave-one-out', got 'bootstrap'"},
      {replaced("repetitions: 50", "repetitions: 2.5"),
       "field 'protocol.repetitions': expected a whole number from 1 to 1000000"},
      {"abc\n", "field '(root)': expected a mapping"},
      {"- 1\n", "field '(root)': expected a mapping"},
      {"format: [1, 2]\n", "field 'format': expected a text"},
      {"format: msmcal-hall-model/1\nmodel: {a: 1}\n", "field 'model': expected a text"},
      {head + "parameters: 1\n", "field 'parameters': expected a mapping"},
      {head + "parameters: [1]\n", "field 'parameters': expected a mapping"},
      {bins, "field 'background_profile.bins_uT': expected a list"},
  };
  for (const auto& [text, expected] : cases) {
    const std::string e = ErrorOf([&] { ParseHallModelYaml(text, "m.yaml"); });
    EXPECT_EQ(e.rfind("m.yaml: ", 0), 0u) << text << " -> " << e;
    EXPECT_NE(e.find(expected), std::string::npos) << text << " -> " << e;
  }
}

}  // namespace
}  // namespace msmcal::results

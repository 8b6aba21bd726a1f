#include "sessions/results/finish_steps.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "mocks/rig/rig_simulator.h"
#include "mocks/rig/truth_io.h"
#include "sessions/interchange/interchange_io.h"
#include "tests/testing/test_files.h"
#include "tests/testing/tiny_sim.h"

namespace msmcal::results {
namespace {

namespace fs = std::filesystem;
using testing::Spit;
using testing::TempDir;

// The command's lines for dt identified by the drives' phases (processing/hall/drive_phase.h):
// the number, and the field model's own verdict that did not identify it; the phases' line
// determined, choosing only the bracket's valley, or not at all.
TEST(FinishSteps, DeltaTLinesOfTheDrivesPhases) {
  hall::DeltaTEstimate e;
  e.status = hall::DeltaTStatus::kIdentified;
  e.method = hall::DeltaTMethod::kDrivePhases;
  e.model = hall::HallModelKind::kLinear;
  e.field_status = hall::DeltaTStatus::kSplitsDisagree;
  e.field_reason = "13 of 50 train/test splits find dt elsewhere";
  e.delta_t_s = 0.5553e-3;
  e.sigma_s = 0.0112e-3;
  EXPECT_EQ(FormatDeltaT(e, hall::HallModelKind::kSine, 0.5582e-3),
            "delta_t = 0.5553 ms +- 0.0112 ms (identified by the drives' phases; the linear "
            "model's profile did not: splits disagree: 13 of 50 train/test splits find dt "
            "elsewhere; the sine model's own dt 0.5582 ms aligns phases, not clocks)");
  hall::DrivePhaseEstimate ph;
  ph.determined = ph.chooses_valley = true;
  ph.delta_t_s = 0.5553e-3;
  ph.sigma_s = 0.0112e-3;
  ph.slow.delta_t_s = 0.407e-3;
  ph.slow.sigma_s = 0.077e-3;
  ph.separation = 873.6;
  ph.fast.coherence = 0.9991;
  ph.slow.coherence = 1.0;
  EXPECT_EQ(FormatDrivePhase(ph, hall::DeltaTBracket::kDrivePhases),
            "drive phases: dt = 0.5553 ms +- 0.0112 ms (the fast drive's valley nearest the slow "
            "drive's 0.407 +- 0.077 ms, the next 874 variances less likely; Hall axes agree "
            "0.999 / 1.000); it brackets the final fit");
  ph.determined = false;
  ph.reason = "the slow drive's phase does not choose";
  EXPECT_EQ(FormatDrivePhase(ph, hall::DeltaTBracket::kDrivePhases),
            "drive phases: dt not determined (the slow drive's phase does not choose); the "
            "likelier valley, 0.5553 ms, brackets the final fit");
  EXPECT_EQ(FormatDrivePhase(ph, hall::DeltaTBracket::kSteadyFieldModel),
            "drive phases: dt not determined (the slow drive's phase does not choose)");
}

TEST(FinishSteps, FailuresAreReturnedNamingTheFile) {
  TempDir dir;
  const SolveStepResult solve = RunSolveStep(dir.path(), solver::PipelineOptions{});
  EXPECT_FALSE(solve.ok());
  EXPECT_NE(solve.error.find("session.yaml"), std::string::npos) << solve.error;
  EXPECT_TRUE(solve.text.empty());

  solver::PipelineOptions bad;
  bad.image_threads = 0;
  const SolveStepResult invalid = RunSolveStep(dir.path(), bad);
  EXPECT_EQ(invalid.error.rfind("solve settings: ", 0), 0u) << invalid.error;

  const HallPredictionStepResult predict =
      RunHallPrediction(dir.path() / "absent.yaml", dir.path() / "in.csv", dir.path() / "out.csv");
  EXPECT_FALSE(predict.ok());
  EXPECT_NE(predict.error.find("absent.yaml"), std::string::npos) << predict.error;
  EXPECT_FALSE(fs::exists(dir.path() / "out.csv"));
}

// `msmcal solve` reads each image through the check `msmcal interchange check` makes: an image
// of another size than camera.yaml's image_size stops the solve naming the file and both sizes
// (it used to go on into the detectors).
TEST(FinishSteps, SolveRefusesAnImageOfTheWrongSizeNamingTheFile) {
  TempDir dir;
  const sim::RigSimulator simulator(testing::TinySim());
  const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/false);
  interchange::WriteRecording(dir.path(), rec);
  const cv::Mat small(rec.camera.height / 2, rec.camera.width, CV_8UC1, cv::Scalar(128));
  for (const auto& f : rec.step1) interchange::WriteImageAtomically(dir.path() / f.file, small);
  for (const auto& f : rec.step2) interchange::WriteImageAtomically(dir.path() / f.file, small);
  const SolveStepResult solve = RunSolveStep(dir.path(), solver::PipelineOptions{});
  ASSERT_FALSE(solve.ok());
  const std::string size = "image is " + std::to_string(rec.camera.width) + "x" +
                           std::to_string(rec.camera.height / 2) +
                           " but camera.yaml image_size is [" + std::to_string(rec.camera.width) +
                           ", " + std::to_string(rec.camera.height) + "]";
  EXPECT_NE(solve.error.find(size), std::string::npos) << solve.error;
  bool names_a_frame = false;
  for (const auto& f : rec.step1) names_a_frame |= solve.error.find(f.file) != std::string::npos;
  for (const auto& f : rec.step2) names_a_frame |= solve.error.find(f.file) != std::string::npos;
  EXPECT_TRUE(names_a_frame) << solve.error;
}

// A simulated folder whose mirror planes are the simulator's truth (the solver has its own
// tests): calibration, then prediction of every reading of the scan recording.
TEST(FinishSteps, HallCalibrationThenPredictionOnASimulatedFolder) {
  TempDir dir;
  const sim::RigSimulator simulator(testing::TinySim());
  const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/true);
  interchange::WriteRecording(dir.path(), rec);
  for (const auto& f : rec.step1) Spit(dir.path() / f.file, "");  // not read by these steps
  for (const auto& f : rec.step2) Spit(dir.path() / f.file, "");

  const HallCalibrationStepResult missing = RunHallCalibration(dir.path(), {});
  EXPECT_NE(missing.error.find("mirror_planes.csv: not found; run `msmcal solve "),
            std::string::npos)
      << missing.error;

  WriteMirrorPlanesCsv(dir.path() / "results" / "mirror_planes.csv",
                       sim::MakeTruth(simulator).mirror_planes);
  hall::HallCalibrationOptions options;
  options.repetitions = 3;
  options.models = {hall::HallModelKind::kLinear};
  const HallCalibrationStepResult cal = RunHallCalibration(dir.path(), options);
  ASSERT_TRUE(cal.ok()) << cal.error;
  EXPECT_EQ(cal.model_file, dir.path() / "results" / "hall_model.yaml");
  EXPECT_EQ(cal.model, hall::HallModelKind::kLinear);
  EXPECT_EQ(cal.text.rfind("Table II (3 random", 0), 0u) << cal.text;
  // The tiny session (2 s recordings, 18 triggers) does not determine dt: the model keeps its own
  // dt for the predictor, the session's is reported as not identified, with the reason.
  EXPECT_NE(cal.text.find("model: linear, delta_t not identified ("), std::string::npos)
      << cal.text;
  EXPECT_FALSE(cal.time_offset.identified());
  ASSERT_FALSE(cal.log.empty());
  EXPECT_EQ(cal.log.back().level, StepLogLine::Level::kWarning);
  EXPECT_NE(cal.log.back().text.find("delta_t not identified"), std::string::npos);
  const HallModelFile file = ReadHallModelYaml(cal.model_file);
  EXPECT_EQ(file.model.delta_t_s, cal.delta_t_s);
  ASSERT_TRUE(file.time_offset.has_value());
  EXPECT_FALSE(file.time_offset->identified());
  EXPECT_EQ(file.time_offset->status, cal.time_offset.status);
  EXPECT_EQ(file.time_offset->reason, cal.time_offset.reason);
  EXPECT_TRUE(std::isnan(file.time_offset->delta_t_s));  // no figure written
  // summary.json "hall": the same verdict, no figure for the session's dt, the candidate named.
  {
    std::ifstream in(dir.path() / "results" / "summary.json");
    const nlohmann::json hall = nlohmann::json::parse(in).at("hall");
    EXPECT_EQ(hall.at("model"), "linear");
    EXPECT_EQ(hall.at("poses").get<size_t>(), sim::MakeTruth(simulator).mirror_planes.size());
    EXPECT_FALSE(hall.at("delta_t_identified").get<bool>());
    EXPECT_TRUE(hall.at("delta_t_s").is_null());
    EXPECT_EQ(hall.at("delta_t_status"), hall::ToString(cal.time_offset.status));
    EXPECT_EQ(hall.at("delta_t_reason"), cal.time_offset.reason);
    EXPECT_EQ(hall.at("model_delta_t_s").get<double>(), cal.delta_t_s);
    EXPECT_EQ(hall.at("delta_t_profile_min_s").get<double>(), cal.time_offset.profile_min_s);
  }

  const fs::path poses = dir.path() / "results" / "hall_poses.csv";
  const HallPredictionStepResult pred =
      RunHallPrediction(cal.model_file, dir.path() / "hall" / "actual.csv", poses);
  ASSERT_TRUE(pred.ok()) << pred.error;
  ASSERT_EQ(pred.log.size(), 1u);  // the time base from the sibling actual_clock.csv
  EXPECT_EQ(pred.log[0].level, StepLogLine::Level::kInfo);
  EXPECT_NE(pred.log[0].text.find("actual_clock.csv"), std::string::npos) << pred.log[0].text;
  EXPECT_EQ(pred.poses, rec.hall_actual->readings.size());
  EXPECT_EQ(ReadHallPosesCsv(poses).size(), pred.poses);

  // Seven poses, fewer than a 4:1 split needs: evaluated leave-one-out, and said so in the
  // heading and in hall_model.yaml's protocol.
  std::vector<dataset::MirrorPlaneRow> seven = sim::MakeTruth(simulator).mirror_planes;
  seven.resize(7);
  WriteMirrorPlanesCsv(dir.path() / "results" / "mirror_planes.csv", seven);
  const HallCalibrationStepResult loo = RunHallCalibration(dir.path(), options);
  ASSERT_TRUE(loo.ok()) << loo.error;
  EXPECT_EQ(loo.text.rfind("Table II (leave-one-out over 7 poses, fewer than the 8 that random "
                           "8:2 splits need;",
                           0),
            0u)
      << loo.text;
  std::ifstream yaml(loo.model_file);
  const std::string text((std::istreambuf_iterator<char>(yaml)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("evaluation: leave-one-out"), std::string::npos) << text;
  EXPECT_NE(text.find("repetitions: 7"), std::string::npos) << text;
  const HallModelFile loo_file = ReadHallModelYaml(loo.model_file);
  EXPECT_TRUE(loo_file.leave_one_out);
  EXPECT_EQ(loo_file.repetitions, 7);
  EXPECT_FALSE(file.leave_one_out);  // the first calibration's: 3 random splits
  EXPECT_EQ(file.repetitions, 3);
}

// A full-size simulated session (15 s recordings, 60 triggers): every model of Table II, and dt
// identified and recovered within 0.05 ms of the simulated sensor delay.
TEST(FinishSteps, HallCalibrationIdentifiesDeltaTOnAFullSizeSession) {
  TempDir dir;
  const sim::RigSimulator simulator{sim::SimOptions{}};
  const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/true);
  interchange::WriteRecording(dir.path(), rec);
  for (const auto& f : rec.step1) Spit(dir.path() / f.file, "");
  for (const auto& f : rec.step2) Spit(dir.path() / f.file, "");
  WriteMirrorPlanesCsv(dir.path() / "results" / "mirror_planes.csv",
                       sim::MakeTruth(simulator).mirror_planes);
  hall::HallCalibrationOptions options;
  options.repetitions = 5;
  const HallCalibrationStepResult cal = RunHallCalibration(dir.path(), options);
  ASSERT_TRUE(cal.ok()) << cal.error;
  const double truth = simulator.options().hall.delta_t_s;
  ASSERT_TRUE(cal.time_offset.identified()) << cal.time_offset.reason;
  EXPECT_NEAR(cal.time_offset.delta_t_s, truth, 0.05e-3);
  EXPECT_LT(cal.time_offset.sigma_s, 0.025e-3);
  EXPECT_NE(cal.text.find(", identified: 5 of 5 splits agree"), std::string::npos) << cal.text;
  const HallModelFile file = ReadHallModelYaml(cal.model_file);
  ASSERT_TRUE(file.time_offset.has_value());
  EXPECT_TRUE(file.time_offset->identified());
  EXPECT_EQ(file.time_offset->delta_t_s, cal.time_offset.delta_t_s);
  EXPECT_EQ(file.time_offset->model, cal.time_offset.model);
  std::ifstream in(dir.path() / "results" / "summary.json");
  const nlohmann::json hall = nlohmann::json::parse(in).at("hall");
  EXPECT_TRUE(hall.at("delta_t_identified").get<bool>());
  EXPECT_EQ(hall.at("delta_t_s").get<double>(), cal.time_offset.delta_t_s);
  EXPECT_EQ(hall.at("delta_t_sigma_s").get<double>(), cal.time_offset.sigma_s);
  EXPECT_EQ(hall.at("delta_t_model"), hall::ToString(cal.time_offset.model));
  EXPECT_EQ(hall.at("test_rms").size(), 3u);
  std::printf("full-size session: dt %.4f ms +- %.4f (%s model), truth %.4f ms\n",
              cal.time_offset.delta_t_s * 1e3, cal.time_offset.sigma_s * 1e3,
              hall::ToString(cal.time_offset.model), truth * 1e3);
}

}  // namespace
}  // namespace msmcal::results

#include "sessions/results/finish_steps.h"

#include <gtest/gtest.h>

#include <fstream>
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
  EXPECT_NE(cal.text.find("model: linear, delta_t = "), std::string::npos) << cal.text;
  EXPECT_EQ(ReadHallModelYaml(cal.model_file).model.delta_t_s, cal.delta_t_s);

  const fs::path poses = dir.path() / "results" / "hall_poses.csv";
  const HallPredictionStepResult pred =
      RunHallPrediction(cal.model_file, dir.path() / "hall" / "actual.csv", poses);
  ASSERT_TRUE(pred.ok()) << pred.error;
  ASSERT_EQ(pred.log.size(), 1u);  // the time base from the sibling actual_clock.csv
  EXPECT_EQ(pred.log[0].level, StepLogLine::Level::kInfo);
  EXPECT_NE(pred.log[0].text.find("actual_clock.csv"), std::string::npos) << pred.log[0].text;
  EXPECT_EQ(pred.poses, rec.hall_actual->readings.size());
  EXPECT_EQ(ReadHallPosesCsv(poses).size(), pred.poses);
}

}  // namespace
}  // namespace msmcal::results

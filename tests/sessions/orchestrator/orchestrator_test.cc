// End-to-end tests of the orchestrator through the real drivers and the mocks (generators over
// loopback SCPI, camera over GigE Vision, Hall MCU over a pty), at a small configuration.
#include "sessions/orchestrator/orchestrator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "mocks/generator/mock_server.h"
#include "mocks/rig/truth_io.h"
#include "processing/solver/pipeline.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/demo_rig.h"
#include "sessions/orchestrator/quality_gate.h"

namespace msmcal::orchestrator {
namespace {

namespace fs = std::filesystem;

// Small but solvable: fewer poses, triggers and frames, short Hall recordings.
sim::SimOptions TinySim() {
  sim::SimOptions o;
  o.seed = 3;
  o.step1.poses = 4;
  o.step2.neutral_frames = 1;
  o.step2.fast_only_frames = 2;
  o.triggers.max_triggers = 18;
  o.hall.background_duration_s = 2.0;
  o.hall.actual_duration_s = 2.0;
  return o;
}

fs::path FreshDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("orch_" + name);
  fs::remove_all(dir);
  return dir;
}

std::string ReadText(const fs::path& f) {
  std::ifstream in(f);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(QualityGate, AcceptsRenderedFramesAndSaysWhyItRejects) {
  const sim::RigSimulator sim(TinySim());
  const dataset::Recording plan = sim.MakeRecording(false);
  GateOptions gate;
  const cv::Mat s1 = sim.RenderStep1Frame(0);
  const GateResult ok = CheckFrame(s1, 1, static_cast<int>(plan.step1[0].beams.size()),
                                   plan.world_board, plan.sliding_board, gate);
  EXPECT_TRUE(ok.accepted) << ok.reason;

  const GateResult wrong_count = CheckFrame(s1, 1, 7, plan.world_board, plan.sliding_board, gate);
  EXPECT_FALSE(wrong_count.accepted);
  EXPECT_NE(wrong_count.reason.find("expected 7 dots"), std::string::npos) << wrong_count.reason;

  cv::Mat saturated = s1.clone();
  saturated(cv::Rect(0, 0, saturated.cols / 2, saturated.rows / 4)).setTo(255);
  const GateResult sat = CheckFrame(saturated, 1, 1, plan.world_board, plan.sliding_board, gate);
  EXPECT_FALSE(sat.accepted);
  EXPECT_NE(sat.reason.find("saturated"), std::string::npos) << sat.reason;

  const cv::Mat blank(s1.size(), CV_8UC1, cv::Scalar(40));
  const GateResult none = CheckFrame(blank, 2, 1, plan.world_board, plan.sliding_board, gate);
  EXPECT_FALSE(none.accepted);
  EXPECT_NE(none.reason.find("world board"), std::string::npos) << none.reason;
}

TEST(Orchestrator, RunsACompleteSessionThroughTheMocksAndTheSolverRecoversTruth) {
  DemoRigOptions ro;
  ro.sim = TinySim();
  DemoRig rig(ro);
  const fs::path dir = FreshDir("e2e");
  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir);
  std::vector<std::string> progress;
  const SessionResult result =
      RunSession(options, rig.Plan(), rig.world(),
                 [&](const std::string& line) { progress.push_back(line); });
  EXPECT_TRUE(result.rig_check.ok);
  EXPECT_TRUE(result.safe_state_confirmed);
  EXPECT_FALSE(rig.generators().unit(1).AnyOutputOn());
  EXPECT_FALSE(rig.generators().unit(2).AnyOutputOn());
  for (const auto& f : result.frames) EXPECT_TRUE(f.accepted) << f.file << ": " << f.reason;
  EXPECT_GT(result.background_readings, 1000u);
  EXPECT_GT(result.actual_readings, 1000u);
  EXPECT_GT(result.actual_edges, 5u);
  EXPECT_FALSE(progress.empty());
  // What the camera delivered over GigE Vision is, pixel for pixel, the simulator's render of
  // the setup the operator action selected (no stale or torn frames, gate leaves pixels alone).
  for (size_t i : {size_t{0}, rig.sim().step1_frames().size() - 1}) {
    const cv::Mat grabbed =
        cv::imread((dir / rig.sim().step1_frames()[i].file).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(grabbed.empty());
    EXPECT_EQ(cv::norm(grabbed, rig.sim().RenderStep1Frame(i), cv::NORM_INF), 0.0) << i;
  }
  {
    const size_t last = rig.sim().step2_frames().size() - 1;
    const cv::Mat grabbed =
        cv::imread((dir / rig.sim().step2_frames()[last].file).string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(cv::norm(grabbed, rig.sim().RenderStep2Frame(last), cv::NORM_INF), 0.0);
  }

  // The folder reads back and passes the shared validator.
  const dataset::Recording rec = interchange::ReadRecording(dir);
  ASSERT_TRUE(rec.hall_actual.has_value());
  ASSERT_TRUE(rec.hall_background.has_value());
  EXPECT_EQ(rec.hall_actual->readings.size(), result.actual_readings);
  EXPECT_NO_THROW(interchange::CheckImageFiles(dir, rec));
  const std::string validator = "/work/shared/tools/validate-interchange";
  if (fs::exists(validator)) {
    EXPECT_EQ(std::system(("/usr/bin/python3 " + validator + " " + dir.string()).c_str()), 0);
  }
  // The grabbed frames are the simulator's renders of the right setup (same scene; render
  // noise differs by frame index): the solver recovers the true planes.
  const solver::SolveOutput out = solver::SolveRecording(rec, [&](const std::string& file) {
    return cv::imread((dir / file).string(), cv::IMREAD_UNCHANGED);
  });
  ASSERT_FALSE(out.planes.empty());
  double s2 = 0;
  for (const auto& pl : out.planes) {
    const geometry::Plane truth =
        rig.sim().MirrorPlaneInWorld(rig.sim().triggers()[pl.j].t_s, sim::DriveMode::kScan);
    const double e = geometry::AngleBetween(pl.plane_in_world.n, truth.n) * 180.0 / M_PI;
    s2 += e * e;
  }
  const double rms_deg = std::sqrt(s2 / out.planes.size());
  EXPECT_LT(rms_deg, 0.2) << "plane normal RMS vs truth";
  const std::string log = ReadText(dir / "session_log.txt");
  EXPECT_NE(log.find("rig check passed"), std::string::npos);
  EXPECT_NE(log.find("safe state: generator outputs off (confirmed)"), std::string::npos);
}

TEST(Orchestrator, ErrorMidRunSwitchesOutputsOffAndIsLogged) {
  DemoRigOptions ro;
  ro.sim = TinySim();
  DemoRig rig(ro);
  const fs::path dir = FreshDir("fail");
  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir);
  options.fail_after_frames = 2;
  bool outputs_were_on = false;
  try {
    RunSession(options, rig.Plan(), rig.world(), [&](const std::string& line) {
      if (line.find("step 1: frame 1/") != std::string::npos)
        outputs_were_on = rig.generators().unit(1).AnyOutputOn() &&
                          rig.generators().unit(2).AnyOutputOn();
    });
    FAIL() << "expected the injected failure";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("injected failure"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(outputs_were_on);
  EXPECT_FALSE(rig.generators().unit(1).AnyOutputOn());
  EXPECT_FALSE(rig.generators().unit(2).AnyOutputOn());
  const std::string log = ReadText(dir / "session_log.txt");
  EXPECT_NE(log.find("ERROR: injected failure"), std::string::npos) << log;
  EXPECT_NE(log.find("safe state: generator outputs off"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(dir / "session.yaml")) << "an aborted session is not complete";
}

TEST(Orchestrator, RigCheckRefusesWithTheListOfProblems) {
  DemoRigOptions ro;
  ro.sim = TinySim();
  DemoRig rig(ro);
  rig.generators().SetReferenceWired(false);
  const fs::path dir = FreshDir("check");
  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir);
  options.camera_address = "127.0.0.9";  // no camera answers there
  try {
    RunSession(options, rig.Plan(), rig.world(), nullptr);
    FAIL() << "expected RigCheckError";
  } catch (const RigCheckError& e) {
    const auto& problems = e.result().problems;
    ASSERT_GE(problems.size(), 2u) << e.what();
    const std::string all = e.what();
    EXPECT_NE(all.find("not locked"), std::string::npos) << all;
    EXPECT_NE(all.find("camera 127.0.0.9"), std::string::npos) << all;
  }
  EXPECT_FALSE(fs::exists(dir / "session.yaml"));
  EXPECT_FALSE(rig.generators().unit(1).AnyOutputOn());
  EXPECT_FALSE(rig.generators().unit(2).AnyOutputOn());
}

}  // namespace
}  // namespace msmcal::orchestrator

// A rig sweep's point (docs/lab-path.md "Rig sweeps"): the plan that reuses a reference session's
// step 1 (PlanWithReferenceStep1), the point folder seeded with the reference's step 1 and
// background Hall recording (SeedSessionFromReference), and the operator of a rig nobody touches
// (FixedRigOperator). No instrument: the session run itself is cli.twin_rig_sweep's.
#include "sessions/orchestrator/reference_steps.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "acquisition/hall/hall_csv_writer.h"
#include "mocks/rig/rig_simulator.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/fixed_rig_operator.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/store/session_store.h"
#include "tests/testing/tiny_sim.h"

namespace msmcal::orchestrator {
namespace {

namespace fs = std::filesystem;

// A reference session folder: the simulator's recording (session.yaml, camera.yaml, both Hall
// recordings), its step 1 images as placeholder files (a seed links them, never decodes them).
dataset::Recording WriteReference(const fs::path& dir) {
  fs::remove_all(dir);
  const sim::RigSimulator sim(msmcal::testing::TinySim());
  dataset::Recording rec = sim.MakeRecording(/*with_hall=*/true);
  interchange::WriteRecording(dir, rec);
  for (const auto& f : rec.step1) {
    fs::create_directories((dir / f.file).parent_path());
    std::ofstream(dir / f.file) << "image " << f.file;
  }
  return rec;
}

// The point's designed plan: the reference's rig with another trigger table and step 2.
dataset::Recording Designed(const dataset::Recording& reference) {
  dataset::Recording d = reference;
  d.hall_actual.reset();
  d.hall_background.reset();
  d.camera.fx += 5;  // the rig file's nominal intrinsics, not the calibrated ones
  d.triggers.resize(3);
  d.step2.resize(2);
  d.step2[1].triggers = {0, 1, 2};
  d.step1 = {{"step1/9999.png", 0, {1}}};
  return d;
}

TEST(PlanWithReferenceStep1, TakesStep1AndCameraFromTheReferenceAndStep2FromTheDesign) {
  const fs::path ref = fs::path(::testing::TempDir()) / "ref_plan";
  const dataset::Recording reference = WriteReference(ref);
  const dataset::Recording designed = Designed(reference);
  const dataset::Recording plan = PlanWithReferenceStep1(reference, "REF", designed);
  ASSERT_EQ(plan.step1.size(), reference.step1.size());
  EXPECT_EQ(plan.step1.front().file, reference.step1.front().file);
  EXPECT_EQ(plan.camera.fx, reference.camera.fx);
  EXPECT_EQ(plan.triggers.size(), 3u);
  EXPECT_EQ(plan.step2.size(), 2u);
  EXPECT_FALSE(plan.hall_background.has_value());
}

TEST(PlanWithReferenceStep1, RefusesAnotherBoardBeamListOrSensorNamingTheField) {
  const fs::path ref = fs::path(::testing::TempDir()) / "ref_refuse";
  const dataset::Recording reference = WriteReference(ref);
  auto message = [&](const dataset::Recording& designed) {
    try {
      (void)PlanWithReferenceStep1(reference, "REF", designed);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  dataset::Recording d = Designed(reference);
  d.world_board.square_mm = 12;
  EXPECT_NE(message(d).find("REF: boards.world = "), std::string::npos) << message(d);
  d = Designed(reference);
  d.beams.pop_back();
  EXPECT_NE(message(d).find("REF: beams = "), std::string::npos) << message(d);
  d = Designed(reference);
  d.camera.width += 2;
  EXPECT_NE(message(d).find("REF: camera size = "), std::string::npos) << message(d);
}

TEST(SeedSessionFromReference, JournalsStep1AndTheBackgroundAsRecordedAndLeavesStep2Pending) {
  const fs::path tmp = fs::path(::testing::TempDir()) / "seed";
  fs::remove_all(tmp);
  const dataset::Recording reference = WriteReference(tmp / "ref");
  const dataset::Recording plan = PlanWithReferenceStep1(reference, "REF", Designed(reference));
  OrchestratorOptions options;
  options.out_dir = tmp / "point";
  options.run_kind = "lab";
  fs::create_directories(tmp / ".point.seeding" / "step1");  // a seed cut short by a kill
  SeedSessionFromReference(options, plan, tmp / "ref");

  EXPECT_FALSE(fs::exists(tmp / ".point.seeding"));
  const SessionJournalState st = ReadSessionJournal(options.out_dir);
  ASSERT_TRUE(st.exists);
  EXPECT_FALSE(st.complete);
  EXPECT_EQ(st.frames_recorded, reference.step1.size());
  std::map<std::string, std::string> steps(st.steps.begin(), st.steps.end());
  EXPECT_EQ(steps[kStepRigCheck], "pending");
  EXPECT_EQ(steps[kStep1], "done");
  EXPECT_EQ(steps[kStepBackground], "done");
  EXPECT_EQ(steps[kStep2], "pending");
  EXPECT_EQ(steps[kStepSessionWritten], "pending");
  // The plan RunSession's resume compares with is the point's.
  EXPECT_EQ(interchange::FormatSessionYaml(LoadSessionPlan(options.out_dir)),
            interchange::FormatSessionYaml(plan));
  for (const auto& f : reference.step1) {
    ASSERT_TRUE(fs::exists(options.out_dir / f.file)) << f.file;
    EXPECT_TRUE(fs::equivalent(options.out_dir / f.file, tmp / "ref" / f.file) ||
                fs::file_size(options.out_dir / f.file) == fs::file_size(tmp / "ref" / f.file));
  }
  const fs::path bg = options.out_dir / "hall" / "background.csv";
  const dataset::HallRecording h = interchange::ReadHallCsv(bg, acquisition::ClockCsvPathFor(bg));
  EXPECT_EQ(h.readings.size(), reference.hall_background->readings.size());
  const store::SystemClock clock;
  const auto journal = store::SessionStore::Open(options.out_dir, clock, /*read_only=*/true);
  EXPECT_EQ(journal->HallReadings("background").size(), h.readings.size());
  EXPECT_EQ(journal->ClockEdges("background").size(), h.clock_edges_us.size());
  EXPECT_TRUE(journal->HallReadings("actual").empty());

  // A folder that holds something is never seeded over.
  EXPECT_THROW(SeedSessionFromReference(options, plan, tmp / "ref"), std::runtime_error);
}

// The operator of a rig nobody touches: the actual Hall recording and step 2 frames with every
// beam pass without a prompt; anything that needs another physical state is refused.
TEST(FixedRigOperator, PassesStep2AndTheActualRecordingRefusesOtherStates) {
  const sim::RigSimulator sim(msmcal::testing::TinySim());
  dataset::Recording plan = sim.MakeRecording(/*with_hall=*/false);
  int64_t now_ns = 1'000'000'000;
  FixedRigOptions o;
  o.mcu_device = "/dev/mcu";
  o.host_clock_ns = [&now_ns] { return now_ns; };
  o.settle_ns = 300'000'000;
  {
    FixedRigOperator op(plan, o);
    EXPECT_EQ(op.PrepareHallRecording(HallRun::kActual), "/dev/mcu");
    for (size_t i = 0; i < plan.step2.size(); ++i) op.PrepareStep2Frame(i);
    camera::FrameInfo early, late;
    early.host_timestamp_ns = now_ns + 100'000'000;
    late.host_timestamp_ns = now_ns + 300'000'000;
    EXPECT_FALSE(op.FrameShowsCurrentSetup(early));
    EXPECT_TRUE(op.FrameShowsCurrentSetup(late));
  }
  {
    FixedRigOperator op(plan, o);
    EXPECT_THROW(op.PrepareStep1Frame(0), FixedRigMismatch);
  }
  {
    FixedRigOperator op(plan, o);
    EXPECT_THROW((void)op.PrepareHallRecording(HallRun::kBackground), FixedRigMismatch);
  }
  plan.step2[0].beams = {1};  // beams 2.. blocked: somebody would have to block them
  FixedRigOperator op(plan, o);
  (void)op.PrepareHallRecording(HallRun::kActual);
  try {
    op.PrepareStep2Frame(0);
    ADD_FAILURE() << "a step 2 frame with beams blocked passed";
  } catch (const FixedRigMismatch& e) {
    EXPECT_NE(std::string(e.what()).find("beams_unblocked = [1]"), std::string::npos) << e.what();
  }
  o.mcu_device.clear();
  EXPECT_THROW((void)FixedRigOperator(plan, o), std::invalid_argument);
  // The one set-up a hook gets before a sweep: the fixed state, every beam unblocked.
  const setup::Setup s = FixedRigSetup(plan);
  EXPECT_EQ(s.state.camera, "C2");
  EXPECT_TRUE(s.state.msm_mounted);
  EXPECT_FALSE(s.state.sliding_plate.mounted);
  EXPECT_EQ(s.state.beams_unblocked.size(), plan.beams.size());
  EXPECT_EQ(setup::SetupFromJson(setup::SetupToJson(s)).state, s.state);
}

}  // namespace
}  // namespace msmcal::orchestrator

// The replay rig in process: a tiny demo acquisition (DemoRig + RunSession, as
// RunDemoAcquisition does) replayed through the real drivers gives an identical folder (frames,
// Hall files, generator transcript, session.yaml); so does a replay of that replay; missing
// recordings are refused naming the file. (Solving is covered by the CLI acceptance test.)
// Runs in its own network namespace (the mock camera serves GigE Vision on 127.0.0.1:3956).
#include "simulation/replay/replay_rig.h"

#include <gtest/gtest.h>

#include <string>

#include "sessions/replay/session_compare.h"
#include "simulation/twin/demo_rig.h"

namespace msmcal::replay {
namespace {

namespace fs = std::filesystem;

// Smaller than the orchestrator tests' TinySim: only acquired here, never solved. The beams
// spread so wide that at the far pose the outer ones miss the sliding plate: the quality gate
// rejects those step 1 frames, so the replay must also reproduce rejected frames (kept as
// rejected/step1_*.png).
sim::SimOptions TinySim() {
  sim::SimOptions o;
  o.seed = 3;
  o.camera.width = 1224;
  o.camera.height = 1024;
  o.camera.fx = o.camera.fy = 1000;
  o.camera.cx = 611.5;
  o.camera.cy = 511.5;
  o.step1.poses = 2;
  o.sliding_board.cols = 5;
  o.sliding_board.rows = 4;
  o.step1.farthest_mm = 130;
  o.step2.neutral_frames = 1;
  o.step2.fast_only_frames = 1;
  o.triggers.max_triggers = 6;
  o.triggers.min_separation_px = 13;
  o.hall.background_duration_s = 1.0;
  o.hall.actual_duration_s = 1.0;
  return o;
}

fs::path FreshDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("replay_rig_" + name);
  fs::remove_all(dir);
  return dir;
}

std::string Describe(const SessionComparison& c) {
  std::string s = c.Table();
  for (const auto& d : c.Differences())
    s += d.file + ": " + ToString(d.verdict) + " " + d.detail + "\n";
  return s;
}

void Replay(const fs::path& source, const fs::path& out) {
  ReplayRigOptions ro;
  ro.source = source;
  ReplayRig rig(ro);
  const orchestrator::OrchestratorOptions o = rig.MakeOrchestratorOptions(out);
  EXPECT_EQ(o.run_kind, "replay");
  orchestrator::RunSession(o, rig.Plan(), rig.world(), nullptr);
}

TEST(ReplayRig, AReplayAndAReplayOfItReproduceTheAcquisition) {
  const fs::path a = FreshDir("a"), b = FreshDir("b"), c = FreshDir("c");
  {
    twin::DemoRigOptions ro;
    ro.sim = TinySim();
    twin::DemoRig rig(ro);
    orchestrator::OrchestratorOptions o = rig.MakeOrchestratorOptions(a);
    o.run_kind = "demo";
    o.run_config_yaml = sim::SimOptionsToYaml(ro.sim);
    orchestrator::RunSession(o, rig.Plan(), rig.world(), nullptr);
  }
  ASSERT_TRUE(fs::exists(a / "generators_transcript.txt"));
  ASSERT_TRUE(fs::exists(a / "rejected")) << "the test needs frames the gate rejected";
  ASSERT_TRUE(fs::exists(a / "step2")) << "the test needs frames the gate accepted";

  Replay(a, b);
  const SessionComparison ab = CompareSessions(a, b);
  EXPECT_TRUE(ab.identical()) << Describe(ab);
  EXPECT_FALSE(ab.original_has_results);
  EXPECT_GE(ab.files.size(), 13u) << Describe(ab);  // transcript, 2 yaml, >= 6 images, 4 Hall
  int rejected = 0;
  for (const auto& f : ab.files) rejected += f.file.rfind("rejected/", 0) == 0 ? 1 : 0;
  EXPECT_GT(rejected, 0) << Describe(ab);

  // The replay's journal names its source and keeps the original run's configuration.
  const orchestrator::SessionJournalState jb = orchestrator::ReadSessionJournal(b);
  EXPECT_EQ(jb.run_kind, "replay");
  fs::path named;
  const SourceRun from_b = ParseReplayRunConfigYaml(jb.run_config_yaml, "b", &named);
  EXPECT_EQ(named, fs::absolute(a).lexically_normal());
  EXPECT_EQ(from_b.kind, "demo");
  EXPECT_EQ(ReadSourceRun(b).config_yaml, sim::SimOptionsToYaml(TinySim()));

  Replay(b, c);  // a replay of a replay
  const SessionComparison ac = CompareSessions(a, c);
  EXPECT_TRUE(ac.identical()) << Describe(ac);

  // Missing recordings are named before any instrument is touched.
  fs::remove(c / "hall" / "actual_clock.csv");
  try {
    ReplayRigOptions ro;
    ro.source = c;
    ReplayRig rig(ro);
    ADD_FAILURE() << "no error for the missing Hall clock file";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("hall/actual_clock.csv"), std::string::npos) << e.what();
  }
  const fs::path bare = FreshDir("bare");
  fs::create_directories(bare);
  try {
    ReplayRigOptions ro;
    ro.source = bare;
    ReplayRig rig(ro);
    ADD_FAILURE() << "no error for a folder without a journal";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no session journal"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace msmcal::replay

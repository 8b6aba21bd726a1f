// The session journal and `resume`: a session killed with SIGKILL (in a death-test child) at a
// chosen point is continued through the same orchestrator code; nothing recorded before the kill
// is taken again or lost.
#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "mocks/generator/mock_server.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/store/session_store.h"
#include "simulation/twin/demo_rig.h"
#include "tests/testing/tiny_sim.h"

namespace msmcal::orchestrator {
namespace {

namespace fs = std::filesystem;
using twin::DemoRig;
using twin::DemoRigOptions;
using twin::SimulatedWorld;

using msmcal::testing::TinySim;

fs::path FreshDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("resume_" + name);
  fs::remove_all(dir);
  return dir;
}

std::string ReadText(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

size_t CountLines(const std::string& text) {
  size_t n = 0;
  for (char c : text) n += c == '\n' ? 1 : 0;
  return n;
}

// Runs a session in a death-test child and SIGKILLs it when a progress line contains `marker`.
void RunAndKillAt(const fs::path& dir, const std::string& marker) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        DemoRigOptions ro;
        ro.sim = TinySim();
        DemoRig rig(ro);
        OrchestratorOptions options = rig.MakeOrchestratorOptions(dir);
        options.run_kind = "demo";
        RunSession(options, rig.Plan(), rig.world(), [&](const std::string& line) {
          if (line.find(marker) != std::string::npos) std::raise(SIGKILL);
        });
      },
      ::testing::KilledBySignal(SIGKILL), "");
}

// Files (relative path -> bytes) of the images a session folder holds.
std::map<std::string, std::string> Images(const fs::path& dir) {
  std::map<std::string, std::string> images;
  for (const char* step : {"step1", "step2"}) {
    if (!fs::exists(dir / step)) continue;
    for (const auto& e : fs::directory_iterator(dir / step))
      if (e.path().extension() == ".png")
        images[std::string(step) + "/" + e.path().filename().string()] = ReadText(e.path());
  }
  return images;
}

SessionResult Resume(const fs::path& dir) {
  DemoRigOptions ro;
  ro.sim = TinySim();
  DemoRig rig(ro);
  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir);
  options.resume = true;
  const dataset::Recording plan = LoadSessionPlan(dir);
  EXPECT_EQ(interchange::FormatSessionYaml(plan), interchange::FormatSessionYaml(rig.Plan()));
  SessionResult r = RunSession(options, plan, rig.world(), nullptr);
  EXPECT_TRUE(r.safe_state_confirmed);
  EXPECT_FALSE(rig.generators().unit(1).AnyOutputOn());
  EXPECT_FALSE(rig.generators().unit(2).AnyOutputOn());
  return r;
}

TEST(ResumeDeathTest, KilledInStep2ContinuesKeepingFramesAndThePartialHallRecording) {
  const fs::path dir = FreshDir("step2");
  RunAndKillAt(dir, "step 2: frame 2/");
  ASSERT_TRUE(fs::exists(dir / "session.db"));
  EXPECT_FALSE(fs::exists(dir / "session.yaml"));
  const SessionJournalState before = ReadSessionJournal(dir);
  ASSERT_TRUE(before.exists);
  EXPECT_FALSE(before.complete);
  EXPECT_EQ(before.run_kind, "demo");
  const std::map<std::string, std::string> images_before = Images(dir);
  const std::string partial_actual = ReadText(dir / "hall" / "actual.csv");
  const std::string background_before = ReadText(dir / "hall" / "background.csv");
  ASSERT_GT(CountLines(partial_actual), 1u);
  // 7 step-1 frames (4 poses + 3 identification frames) and 2 step-2 frames were journalled.
  ASSERT_EQ(before.frames_recorded, images_before.size());
  ASSERT_GE(before.frames_recorded, 9u);

  const SessionResult r = Resume(dir);
  EXPECT_TRUE(r.resumed);
  size_t kept = 0;
  for (const auto& f : r.frames) {
    EXPECT_TRUE(f.accepted) << f.file << ": " << f.reason;
    kept += f.from_journal ? 1 : 0;
  }
  EXPECT_EQ(kept, before.frames_recorded);
  // Nothing recorded before the kill was taken again or changed.
  const std::map<std::string, std::string> images_after = Images(dir);
  for (const auto& [file, bytes] : images_before) {
    ASSERT_TRUE(images_after.count(file)) << file;
    EXPECT_EQ(images_after.at(file), bytes) << file << " changed";
  }
  EXPECT_GT(images_after.size(), images_before.size());
  EXPECT_EQ(ReadText(dir / "hall" / "background.csv"), background_before);
  ASSERT_EQ(r.partial_hall_files.size(), 1u);
  EXPECT_EQ(r.partial_hall_files[0], "hall/actual.partial-1.csv");
  EXPECT_EQ(ReadText(dir / "hall" / "actual.partial-1.csv"), partial_actual);
  EXPECT_TRUE(fs::exists(dir / "hall" / "actual.partial-1_clock.csv"));

  // The session is complete and consistent: interchange folder and journal agree.
  const dataset::Recording rec = interchange::ReadRecording(dir);
  EXPECT_EQ(rec.step1.size() + rec.step2.size(), r.frames.size());
  const SessionJournalState after = ReadSessionJournal(dir);
  EXPECT_TRUE(after.complete);
  for (const auto& [name, state] : after.steps) EXPECT_EQ(state, "done") << name;
  const store::SystemClock clock;
  auto journal = store::SessionStore::Open(dir, clock, /*read_only=*/true);
  EXPECT_EQ(journal->IntegrityCheck(), "ok");
  ASSERT_TRUE(rec.hall_actual && rec.hall_background);
  EXPECT_EQ(journal->HallReadings("actual").size(), rec.hall_actual->readings.size());
  EXPECT_EQ(journal->HallReadings("background").size(), rec.hall_background->readings.size());
  EXPECT_EQ(journal->ClockEdges("actual"), rec.hall_actual->clock_edges_us);
  EXPECT_EQ(journal->Frames().size(), r.frames.size());
  for (const auto& f : journal->Frames())
    EXPECT_NE(f.quality_json.find("\"dots_found\""), std::string::npos) << f.quality_json;
  bool resumed_event = false;
  int with_generator_time = 0;
  for (const auto& e : journal->Events()) {
    resumed_event = resumed_event || e.message.find("RESUMED") != std::string::npos;
    // Generator time: only while the outputs are on (from the start trigger to the safe state).
    if (e.message.find("rig check") != std::string::npos ||
        e.message.find("safe state") != std::string::npos) {
      EXPECT_FALSE(e.generator_time_s) << e.message;
    }
    if (e.message.find("step 2: frame") != std::string::npos) {
      ASSERT_TRUE(e.generator_time_s) << e.message;
      EXPECT_GT(*e.generator_time_s, 0.0) << e.message;
      ++with_generator_time;
    }
  }
  EXPECT_TRUE(resumed_event);
  EXPECT_GT(with_generator_time, 0);
  EXPECT_GE(journal->Instruments().size(), 4u);  // two generators, camera, Hall MCU
  const std::string transcript = ReadText(dir / "generators_transcript.txt");
  EXPECT_NE(transcript.find("unit1 > *IDN?"), std::string::npos);
  EXPECT_NE(transcript.find("# resumed"), std::string::npos);

  // A complete session resumes to "nothing to do"; a different plan is refused.
  const SessionResult again = Resume(dir);
  for (const auto& f : again.frames) EXPECT_TRUE(f.from_journal) << f.file;
  DemoRigOptions other;
  other.sim = TinySim();
  other.sim.step1.poses = 5;
  DemoRig rig(other);
  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir);
  options.resume = true;
  try {
    RunSession(options, rig.Plan(), rig.world(), nullptr);
    FAIL() << "a different plan must be refused";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("differs from the plan"), std::string::npos) << e.what();
  }
}

// Killed right after the last step 2 frame: the resume has no frame left to take, and its actual
// Hall recording (taken again: the one cut short is kept aside) still covers the whole of the
// simulator's recording (OrchestratorOptions::actual_min_seconds), not the instant a step 2
// with nothing to do lasts (it was ~0.1 s: too few readings and clock edges for the Hall
// calibration, the fault campaign's mcu-stall row failed on it under load).
TEST(ResumeDeathTest, KilledAfterTheLastStep2FrameRecordsTheWholeActualHallRecordingAgain) {
  const fs::path dir = FreshDir("step2_last");
  const dataset::Recording plan = [] {
    DemoRigOptions ro;
    ro.sim = TinySim();
    return DemoRig(ro).Plan();
  }();
  const std::string n = std::to_string(plan.step2.size());
  RunAndKillAt(dir, "step 2: frame " + n + "/" + n + " ");
  const SessionJournalState before = ReadSessionJournal(dir);
  ASSERT_TRUE(before.exists);
  ASSERT_EQ(before.frames_recorded, plan.step1.size() + plan.step2.size());

  const SessionResult r = Resume(dir);
  for (const auto& f : r.frames) EXPECT_TRUE(f.from_journal) << f.file;
  ASSERT_EQ(r.partial_hall_files.size(), 1u);
  const dataset::Recording rec = interchange::ReadRecording(dir);
  ASSERT_TRUE(rec.hall_actual);
  const auto& readings = rec.hall_actual->readings;
  ASSERT_GE(readings.size(), 2u);
  const double duration_s = TinySim().hall.actual_duration_s;
  const double rate_hz = TinySim().hall.sample_rate_hz;
  const double span_s = 1e-6 * (readings.back().mcu_time_us - readings.front().mcu_time_us);
  EXPECT_GE(span_s, duration_s - 2.0 / rate_hz) << readings.size() << " readings";
  EXPECT_GE(readings.size(), static_cast<size_t>(duration_s * rate_hz) - 2);
  EXPECT_NE(ReadText(dir / "session_log.txt").find("actual recording held until it covers"),
            std::string::npos);
  EXPECT_TRUE(ReadSessionJournal(dir).complete);
}

TEST(ResumeDeathTest, KilledInStep1ContinuesFromTheNextFrame) {
  const fs::path dir = FreshDir("step1");
  RunAndKillAt(dir, "step 1: frame 2/");
  const SessionJournalState before = ReadSessionJournal(dir);
  ASSERT_EQ(before.frames_recorded, 2u);
  const std::map<std::string, std::string> images_before = Images(dir);
  const SessionResult r = Resume(dir);
  ASSERT_GE(r.frames.size(), 3u);
  EXPECT_TRUE(r.frames[0].from_journal && r.frames[1].from_journal);
  EXPECT_FALSE(r.frames[2].from_journal);
  EXPECT_TRUE(r.partial_hall_files.empty());
  for (const auto& [file, bytes] : images_before) EXPECT_EQ(ReadText(dir / file), bytes) << file;
  EXPECT_TRUE(ReadSessionJournal(dir).complete);
  EXPECT_NO_THROW(interchange::ReadRecording(dir));
}

TEST(Resume, RefusesAFolderWithoutAJournal) {
  const fs::path dir = FreshDir("none");
  fs::create_directories(dir);
  EXPECT_FALSE(ReadSessionJournal(dir).exists);
  try {
    LoadSessionPlan(dir);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no session journal"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace msmcal::orchestrator

// `msmcal plan`'s design from the rig file: the plan reads back with the interchange reader,
// every trigger is in exactly one scan frame, no two triggers of a frame are closer than the
// separation rule, and what the rig's limits forbid is refused naming field and limit.
#include "sessions/plan/session_plan.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "processing/plan/frame_design.h"
#include "processing/signal/rig_signals.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::plan {
namespace {

namespace fs = std::filesystem;

fs::path SourceDir() {
  const char* src = std::getenv("MSMCAL_SOURCE_DIR");
  return src != nullptr ? src : MSMCAL_TEST_SOURCE_DIR;
}

std::string ExampleText() {
  std::ifstream in(SourceDir() / "config" / "rig.yaml");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t p = text.find(from);
  EXPECT_NE(p, std::string::npos) << from;
  if (p != std::string::npos) text.replace(p, from.size(), to);
  return text;
}

TEST(SessionPlan, TheExamplePlanReadsBackAndCoversEveryTriggerOnce) {
  const rig::RigFile rig = rig::LoadRigFile(SourceDir() / "config" / "rig.yaml");
  const dataset::Recording plan = DesignSessionPlan(rig);
  const fs::path dir = fs::path(::testing::TempDir()) / "session_plan_example";
  fs::remove_all(dir);
  WritePlanFolder(dir, plan);
  dataset::Recording back;
  std::ifstream in(dir / "session.yaml");
  std::stringstream text;
  text << in.rdbuf();
  interchange::ParseSessionYaml(text.str(), "session.yaml", &back);
  back.camera = interchange::ReadCameraYaml(dir / "camera.yaml");
  EXPECT_EQ(interchange::CheckRecording(back), "");
  EXPECT_EQ(back.camera.width, 2448);
  EXPECT_DOUBLE_EQ(back.camera.fx, 2000);
  EXPECT_DOUBLE_EQ(back.drive.fast.frequency_hz, 205);
  EXPECT_DOUBLE_EQ(back.drive.pattern_period_s, 0.2);
  EXPECT_DOUBLE_EQ(back.clock_frequency_hz, 5);
  ASSERT_EQ(back.beams.size(), 3u);
  EXPECT_EQ(back.beams[2].role, dataset::BeamRole::kValidate);
  EXPECT_EQ(back.step1.size(), plan.step1.size());
  EXPECT_EQ(back.step2.size(), plan.step2.size());
  EXPECT_EQ(CheckPlanAgainstRig(back, rig), "");

  // The trigger table is processing/signal's design for the rig's drive.
  const signal::TriggerDesign d = signal::DesignTriggers(
      rig.generators.signals.fast, rig.generators.signals.slow, rig.generators.signals.trigger);
  ASSERT_EQ(back.triggers.size(), d.times_s.size());
  for (size_t j = 0; j < d.times_s.size(); ++j)
    EXPECT_NEAR(back.triggers[j].t_s, d.times_s[j], 1e-12);

  // Every trigger in exactly one scan frame; no two triggers of any frame closer than the rule.
  std::map<int, int> scans;
  auto point = [&](int j) {
    const double t = back.triggers.at(j).t_s;
    return SignalPoint{signal::SineUnit(rig.generators.signals.fast, t),
                       signal::SineUnit(rig.generators.signals.slow, t)};
  };
  size_t neutral = 0, fast_only = 0;
  for (const auto& f : back.step2) {
    if (f.kind == dataset::Step2Kind::kNeutral) ++neutral;
    if (f.kind == dataset::Step2Kind::kFastOnly) {
      ++fast_only;
      EXPECT_LE(f.triggers.size(), 4u);
      for (size_t a = 0; a < f.triggers.size(); ++a)
        for (size_t b = a + 1; b < f.triggers.size(); ++b)
          EXPECT_GE(std::abs(point(f.triggers[a]).fast - point(f.triggers[b]).fast), 0.5) << f.file;
    }
    if (f.kind != dataset::Step2Kind::kScan) continue;
    EXPECT_LE(f.triggers.size(), 3u) << f.file;
    for (int j : f.triggers) ++scans[j];
    for (size_t a = 0; a < f.triggers.size(); ++a)
      for (size_t b = a + 1; b < f.triggers.size(); ++b)
        EXPECT_GE(Distance(point(f.triggers[a]), point(f.triggers[b])),
                  rig.step2.frame_min_separation)
            << f.file;
  }
  EXPECT_EQ(neutral, 2u);
  EXPECT_EQ(fast_only, 3u);
  ASSERT_EQ(scans.size(), back.triggers.size());
  for (const auto& [j, n] : scans) EXPECT_EQ(n, 1) << "trigger " << j;

  // Step 1: 7 poses, every frame 3 times, identification frames (one beam alone) at the last.
  int single = 0, background = 0;
  for (size_t i = 0; i < back.step1.size(); ++i) {
    EXPECT_EQ(back.step1[i].file, FrameFile("step1", i));
    if (i % 3 > 0) {
      EXPECT_EQ(back.step1[i].beams, back.step1[i - 1].beams);
    }
    if (back.step1[i].beams.size() == 1) {
      ++single;
      EXPECT_EQ(back.step1[i].pose, 6);
    }
    if (back.step1[i].beams.empty()) ++background;
  }
  EXPECT_EQ(single, 3 * 3);
  EXPECT_EQ(background, 6 * 3);

  const PlanSummary s = SummarisePlan(back, rig);
  EXPECT_EQ(s.setups, static_cast<int>(setup::PlanSetups(back, PoseGeometryOf(rig)).setups.size()));
  EXPECT_GT(s.expected_duration_s, s.setups * kSecondsPerChange);
  EXPECT_GT(s.disk_bytes, (back.step1.size() + back.step2.size()) * 2448ull * 2048ull);
  EXPECT_NE(s.text.find("prompts: " + std::to_string(s.setups)), std::string::npos) << s.text;
}

std::string LoadError(const std::string& text) {
  try {
    const rig::RigFile rig = rig::ParseRigFile(text, "rig.yaml");
    (void)DesignSessionPlan(rig);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(SessionPlan, ADriveOutsideTheWindowIsRefusedNamingFieldAndLimit) {
  const std::string e =
      LoadError(Replace(ExampleText(), "frequency_hz: 205,", "frequency_hz: 230,"));
  EXPECT_NE(e.find("generators.unit1.ch1 (fast_coil): frequency_hz = 230 outside the window "
                   "[195, 215] Hz"),
            std::string::npos)
      << e;
}

TEST(SessionPlan, ATriggerDesignOverTheDutyLimitIsRefusedNamingFieldAndLimit) {
  const std::string e =
      LoadError(Replace(ExampleText(), "pulse_width_s: 1.0e-6", "pulse_width_s: 1.0e-4"));
  EXPECT_NE(e.find("generators.signals: trigger design: duty = "), std::string::npos) << e;
  EXPECT_NE(e.find("exceeds trigger.max_duty = 0.01"), std::string::npos) << e;
}

// A hand-edited plan checked against the rig (what `session run --dry-run` does).
TEST(SessionPlan, APlanBeyondTheRigsLimitsIsRefused) {
  const rig::RigFile rig = rig::LoadRigFile(SourceDir() / "config" / "rig.yaml");
  dataset::Recording plan = DesignSessionPlan(rig);
  dataset::Recording edited = plan;
  edited.drive.fast.amplitude_vpp = 6;
  EXPECT_EQ(CheckPlanAgainstRig(edited, rig),
            "plan drive: generators.unit1.ch1 (fast_coil): amplitude_vpp = 6 outside the limit "
            "[0, 4] Vpp");
  edited = plan;
  edited.drive.fast.phase_deg = 10;
  EXPECT_NE(CheckPlanAgainstRig(edited, rig).find("differs from the rig file's"),
            std::string::npos);
  edited = plan;
  while (edited.triggers.size() < 2100)
    edited.triggers.push_back({static_cast<int>(edited.triggers.size()), 0.1});
  EXPECT_EQ(CheckPlanAgainstRig(edited, rig),
            "plan triggers: 2100 triggers exceed generators.signals.trigger.max_triggers = 2000");
  edited = plan;
  edited.camera.width = 1920;
  EXPECT_NE(CheckPlanAgainstRig(edited, rig).find("image_size = [1920, 2048]"), std::string::npos);
}

}  // namespace
}  // namespace msmcal::plan

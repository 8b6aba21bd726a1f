// Set-ups designed from a plan: grouping (only physical changes make a new set-up), the changes
// list, the console text rendered from the Setup, and the JSON form the hooks read.
#include "sessions/setup/setup.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "sessions/plan/session_plan.h"
#include "sessions/rig/rig_file.h"

namespace msmcal::setup {
namespace {

rig::RigFile Example() {
  const char* src = std::getenv("MSMCAL_SOURCE_DIR");
  return rig::LoadRigFile(std::filesystem::path(src != nullptr ? src : MSMCAL_TEST_SOURCE_DIR) /
                          "config" / "rig.yaml");
}

TEST(SetupTest, JsonRoundTripKeepsEveryField) {
  const rig::RigFile rig = Example();
  const dataset::Recording plan = plan::DesignSessionPlan(rig);
  const SetupPlan sp = PlanSetups(plan, plan::PoseGeometryOf(rig));
  ASSERT_GT(sp.setups.size(), 4u);
  for (setup::Setup s : sp.setups) {
    const std::string json = SetupToJson(s);
    EXPECT_EQ(json.find('\n'), std::string::npos);  // one line on the hook's stdin
    s.frame_indices.clear();                        // not carried
    EXPECT_EQ(SetupFromJson(json), s) << json;
  }
  // The fields and names of the contract (docs/lab-path.md).
  const nlohmann::json j = nlohmann::json::parse(SetupToJson(sp.setups.front()));
  EXPECT_EQ(j["msmcal_setup"], 1);
  EXPECT_EQ(j["kind"], "setup");
  EXPECT_EQ(j["block"], 1);
  EXPECT_EQ(j["of"], static_cast<int>(sp.setups.size()));
  EXPECT_EQ(j["for"]["step"], "step1");
  EXPECT_EQ(j["for"]["frames"][0], "step1/0000.png");
  EXPECT_EQ(j["camera"], "C1");
  EXPECT_EQ(j["msm_mounted"], false);
  EXPECT_EQ(j["top_frame_mounted"], true);
  EXPECT_EQ(j["sliding_plate"]["mounted"], true);
  EXPECT_EQ(j["sliding_plate"]["pose"], 0);
  EXPECT_EQ(j["sliding_plate"]["distance_mm"], 35.0);
  EXPECT_EQ(j["sliding_plate"]["tilt_deg"], 12.0);
  EXPECT_EQ(j["beams_unblocked"], nlohmann::json({1, 2, 3}));
  EXPECT_EQ(j["drive"], "off");
  EXPECT_TRUE(j["changes"].is_array());
  EXPECT_EQ(j["text"], sp.setups.front().text);
  const nlohmann::json t = nlohmann::json::parse(TruthRequestJson("/tmp/s/truth"));
  EXPECT_EQ(
      t, nlohmann::json({{"msmcal_setup", 1}, {"kind", "truth_request"}, {"dir", "/tmp/s/truth"}}));
}

TEST(SetupTest, ParsingRefusesWhatIsNotASetupNamingTheField) {
  auto error = [](const std::string& text) {
    try {
      SetupFromJson(text);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_NE(error(R"({"msmcal_setup": 1, "kind": "truth_request", "dir": "/x"})").find("kind"),
            std::string::npos);
  setup::Setup s;
  s.block = 1;
  s.of = 1;
  s.state.beams_unblocked = {1};
  nlohmann::json j = nlohmann::json::parse(SetupToJson(s));
  j["drive"] = "half";
  EXPECT_NE(error(j.dump()).find("drive = 'half'"), std::string::npos);
  j = nlohmann::json::parse(SetupToJson(s));
  j.erase("beams_unblocked");
  EXPECT_NE(error(j.dump()).find("beams_unblocked: missing"), std::string::npos);
}

// A new set-up exactly where the physical state changes: the plan's frames are covered once, in
// order; consecutive set-ups of one step differ in state; `changes` lists what differs.
TEST(SetupTest, SetupsChangeOnlyWithThePhysicalState) {
  const rig::RigFile rig = Example();
  const dataset::Recording plan = plan::DesignSessionPlan(rig);
  const SetupPlan sp = PlanSetups(plan, plan::PoseGeometryOf(rig));
  std::vector<std::string> covered;
  for (size_t k = 0; k < sp.setups.size(); ++k) {
    const setup::Setup& s = sp.setups[k];
    EXPECT_EQ(s.block, static_cast<int>(k) + 1);
    covered.insert(covered.end(), s.frames.begin(), s.frames.end());
    if (k > 0) {
      EXPECT_FALSE(sp.setups[k - 1].step == s.step && sp.setups[k - 1].state == s.state) << k;
      EXPECT_FALSE(s.changes.empty()) << k;
    }
    EXPECT_NE(
        s.text.find("=== [" + std::to_string(k + 1) + "/" + std::to_string(sp.setups.size()) + "]"),
        std::string::npos);
  }
  std::vector<std::string> all;
  for (const auto& f : plan.step1) all.push_back(f.file);
  for (const auto& f : plan.step2) all.push_back(f.file);
  EXPECT_EQ(covered, all);
  // The example: 3 exposures of every step 1 frame share a set-up; step 2 is one set-up (every
  // frame with every beam: neither the triggers nor the drive mode are physical, the generators
  // switch the drives per frame); plus the two Hall set-ups.
  EXPECT_EQ(sp.setups.size() - 2, plan.step1.size() / 3 + 1);
  const setup::Setup& s2all = sp.setups.back();
  EXPECT_EQ(s2all.step, SetupStep::kStep2);
  EXPECT_EQ(s2all.frames.size(), plan.step2.size());
  EXPECT_EQ(s2all.drive, Drive::kOff);  // information: the first frame is a neutral one
  for (const auto& c : s2all.changes) EXPECT_EQ(c.find("drive"), std::string::npos) << c;
  EXPECT_NE(s2all.text.find("Frames: 2 neutral (drives off), 3 fast-only (fast drive only) and "
                            "25 scan (both drives); the generators switch the drives for each "
                            "frame, nothing to change at the rig."),
            std::string::npos)
      << s2all.text;
  // A change of beams still asks, whatever the drive mode.
  dataset::Recording blocked = plan;
  blocked.step2.back().beams = {1, 2};
  const SetupPlan sb = PlanSetups(blocked, plan::PoseGeometryOf(rig));
  ASSERT_EQ(sb.setups.size(), sp.setups.size() + 1);
  EXPECT_EQ(sb.setups.back().changes, std::vector<std::string>{"block beam 3"});
  EXPECT_EQ(sb.setups.back().drive, Drive::kScan);
  const setup::Setup& bg = sp.setups.at(sp.background_setup);
  EXPECT_EQ(bg.step, SetupStep::kHallBackground);
  EXPECT_FALSE(bg.state.top_frame_mounted);
  EXPECT_NE(std::find(bg.changes.begin(), bg.changes.end(), "remove the mirror's top frame"),
            bg.changes.end());
  EXPECT_NE(std::find(bg.changes.begin(), bg.changes.end(), "remove the sliding plate"),
            bg.changes.end());
  // A background frame after an all-beams frame: every beam blocked, nothing else changes.
  const setup::Setup& s2 = sp.setups.at(1);
  EXPECT_TRUE(s2.state.beams_unblocked.empty());
  EXPECT_EQ(s2.changes, std::vector<std::string>{"block beams 1, 2 and 3"});
  const setup::Setup& s3 = sp.setups.at(2);  // pose 2, all beams
  EXPECT_EQ(s3.changes,
            (std::vector<std::string>{"move the sliding plate to pose 2 of 7 (about 46 mm from "
                                      "the mirror position towards the source, tilted -12 deg)",
                                      "unblock beams 1, 2 and 3"}));
}

// The console text is rendered from the Setup's fields: another state, another text.
TEST(SetupTest, TheTextIsRenderedFromTheSetup) {
  const rig::RigFile rig = Example();
  const dataset::Recording plan = plan::DesignSessionPlan(rig);
  SetupPlan sp = PlanSetups(plan, plan::PoseGeometryOf(rig));
  setup::Setup s = sp.setups.front();
  EXPECT_EQ(RenderSetupText(s, plan, false), s.text);
  EXPECT_NE(s.text.find("Unblock beams 1, 2 and 3 (all beams)."), std::string::npos) << s.text;
  EXPECT_NE(s.text.find("about 35 mm"), std::string::npos) << s.text;
  s.state.beams_unblocked = {2};
  s.state.sliding_plate.distance_mm = 80;
  const std::string other = RenderSetupText(s, plan, false);
  EXPECT_NE(other.find("Unblock beam 2 only; block beams 1 and 3"), std::string::npos) << other;
  EXPECT_NE(other.find("about 80 mm"), std::string::npos) << other;
}

}  // namespace
}  // namespace msmcal::setup

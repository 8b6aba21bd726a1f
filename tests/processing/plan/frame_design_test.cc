// Pure frame lists: step 1 per pose (background, identification, close poses, exposures) and
// the trigger grouping under a separation rule.
#include "processing/plan/frame_design.h"

#include <gtest/gtest.h>

#include <cmath>

namespace msmcal::plan {
namespace {

TEST(FrameDesign, Step1PerPoseWithBackgroundIdentificationAndExposures) {
  Step1FrameOptions o;
  o.poses = 3;
  o.beams = 2;
  o.exposures = 1;
  const auto f = DesignStep1Frames(o);
  // Pose 0 and 1: all + background; pose 2 (last): all, then beam 1 alone, beam 2 alone.
  ASSERT_EQ(f.size(), 7u);
  EXPECT_EQ(f[0].beams, (std::vector<int>{1, 2}));
  EXPECT_TRUE(f[1].beams.empty());
  EXPECT_EQ(f[4].pose, 2);
  EXPECT_EQ(f[4].beams, (std::vector<int>{1, 2}));
  EXPECT_EQ(f[5].beams, std::vector<int>{1});
  EXPECT_EQ(f[6].beams, std::vector<int>{2});
  EXPECT_EQ(f[6].file, "step1/0006.png");
  // A close pose: one frame per beam instead of the all-beams frame, background kept.
  o.close_pose = {false, true, false};
  const auto c = DesignStep1Frames(o);
  ASSERT_EQ(c.size(), 8u);
  EXPECT_EQ(c[2].beams, std::vector<int>{1});
  EXPECT_EQ(c[3].beams, std::vector<int>{2});
  EXPECT_TRUE(c[4].beams.empty());
  // Exposures: every frame K times in a row, renumbered.
  o.close_pose.clear();
  o.exposures = 3;
  const auto r = DesignStep1Frames(o);
  ASSERT_EQ(r.size(), 21u);
  for (size_t i = 0; i < r.size(); ++i) {
    EXPECT_EQ(r[i].file, FrameFile("step1", i));
    EXPECT_EQ(r[i].beams, f[i / 3].beams);
    EXPECT_EQ(r[i].pose, f[i / 3].pose);
  }
  o.exposures = 0;
  EXPECT_THROW(DesignStep1Frames(o), std::invalid_argument);
}

// The separation rule holds for any trigger layout: first fit never breaks it.
TEST(FrameDesign, GroupsKeepTheRuleAndCoverEveryIndexOnce) {
  std::vector<SignalPoint> p;
  for (int i = 0; i < 200; ++i) p.push_back({std::sin(i * 0.37), std::cos(i * 0.11)});
  const auto groups = GroupBySeparation(p, 4, 0.6);
  std::vector<int> seen(p.size(), 0);
  for (const auto& g : groups) {
    EXPECT_LE(g.size(), 4u);
    for (size_t a = 0; a < g.size(); ++a) {
      ++seen[g[a]];
      for (size_t b = a + 1; b < g.size(); ++b) EXPECT_GE(Distance(p[g[a]], p[g[b]]), 0.6);
    }
  }
  for (int n : seen) EXPECT_EQ(n, 1);
  // Points all within the rule of each other: one per group.
  const std::vector<SignalPoint> close = {{0, 0}, {0.1, 0}, {0, 0.1}};
  EXPECT_EQ(GroupBySeparation(close, 3, 0.5).size(), 3u);
  EXPECT_THROW(GroupBySeparation(p, 0, 0.6), std::invalid_argument);
}

TEST(FrameDesign, FastOnlyGroupsCompareTheFastAxisAndStartApart) {
  std::vector<SignalPoint> p;
  for (int i = 0; i < 40; ++i) p.push_back({std::sin(i * 0.5), 0.9});
  const auto groups = ChooseFastOnlyGroups(p, 3, 4, 0.5);
  ASSERT_EQ(groups.size(), 3u);
  for (const auto& g : groups) {
    EXPECT_LE(g.size(), 4u);
    for (size_t a = 0; a < g.size(); ++a)
      for (size_t b = a + 1; b < g.size(); ++b)
        EXPECT_GE(std::abs(p[g[a]].fast - p[g[b]].fast), 0.5);
  }
  EXPECT_NE(groups[0], groups[1]);
}

}  // namespace
}  // namespace msmcal::plan

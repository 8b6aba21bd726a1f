#include "sessions/report/verdict.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace msmcal::report {
namespace {

// Normalised errors ne (sqrt(e^T C^-1 e / 2)) whose NEES 2 ne^2 are the chi2(2) quantiles at
// (i + 0.5) / n: an exactly honest sample.
std::vector<double> HonestSample(int n, double scale = 1.0) {
  std::vector<double> ne;
  for (int i = 0; i < n; ++i) {
    const double nees = ChiSquareQuantile((i + 0.5) / n, 2);
    ne.push_back(scale * std::sqrt(nees / 2));
  }
  return ne;
}

TEST(ChiSquare, QuantilesMatchTables) {
  // Exact for 2 dof; Wilson-Hilferty against tabulated values for larger dof.
  EXPECT_NEAR(ChiSquareQuantile(0.95, 2), 5.9915, 1e-4);
  EXPECT_NEAR(ChiSquareQuantile(0.025, 36), 21.336, 0.02);
  EXPECT_NEAR(ChiSquareQuantile(0.975, 36), 54.437, 0.05);
  EXPECT_NEAR(ChiSquareQuantile(0.5, 10), 9.342, 0.01);
  EXPECT_NEAR(ChiSquareQuantile(0.999, 100), 149.449, 0.2);
  EXPECT_THROW(ChiSquareQuantile(1.0, 3), std::invalid_argument);
}

TEST(ChiSquare, EllipseFractionsAreTheIssuesFigures) {
  EXPECT_NEAR(ChiSquare2Cdf(1), 0.393, 1e-3);
  EXPECT_NEAR(ChiSquare2Cdf(4), 0.865, 1e-3);
  EXPECT_NEAR(ChiSquare2Cdf(9), 0.989, 1e-3);
  EXPECT_EQ(ChiSquare2Cdf(-1), 0);
}

TEST(Verdict, NeesPassesHonestSigmasAndFlagsOverAndUnderConfidence) {
  EXPECT_EQ(JudgeNees(HonestSample(50)).level, Level::kPass);
  // Errors 1.3x the sigmas: NEES 1.69 x 2 = 3.4, outside the 95 % band for 50 dots but within 2x.
  const VerdictLine over = JudgeNees(HonestSample(50, 1.3));
  EXPECT_EQ(over.level, Level::kWarn) << over.figure;
  EXPECT_NE(over.figure.find("over-confident"), std::string::npos);
  EXPECT_EQ(JudgeNees(HonestSample(50, 2.0)).level, Level::kFail);
  EXPECT_EQ(JudgeNees(HonestSample(50, 0.5)).level, Level::kFail);
  EXPECT_NE(JudgeNees(HonestSample(50, 0.8)).figure.find("pessimistic"), std::string::npos);
  EXPECT_EQ(JudgeNees({}).level, Level::kFail);
}

TEST(Verdict, EllipseCoverageAgainstBinomialTolerances) {
  const VerdictLine honest = JudgeEllipseCoverage(HonestSample(100));
  EXPECT_EQ(honest.level, Level::kPass) << honest.figure;
  EXPECT_NE(honest.figure.find("expected 39 / 86 / 99 %"), std::string::npos) << honest.figure;
  // Every dot just outside its 1-sigma ellipse (0 % inside against 39 %): far beyond 3 SE.
  EXPECT_EQ(JudgeEllipseCoverage(std::vector<double>(100, 0.8)).level, Level::kFail);
  // Few dots: wide tolerances; one dot of 4 inside 1 sigma is fine.
  EXPECT_EQ(JudgeEllipseCoverage({0.5, 0.9, 1.0, 1.2}).level, Level::kPass);
}

TEST(Verdict, PlanesDroppedFramesAndReadingsThresholds) {
  EXPECT_EQ(JudgePlanes(18, 18).level, Level::kPass);
  EXPECT_EQ(JudgePlanes(9, 10).level, Level::kPass);  // exactly 90 %
  EXPECT_EQ(JudgePlanes(8, 10).level, Level::kWarn);
  EXPECT_EQ(JudgePlanes(6, 10).level, Level::kFail);
  EXPECT_EQ(JudgePlanes(5, 0).level, Level::kFail);

  EXPECT_EQ(JudgeDroppedFrames(0, 40, "", 0).level, Level::kPass);
  EXPECT_EQ(JudgeDroppedFrames(2, 40, "r", 2).level, Level::kPass);  // 5 %
  const VerdictLine some = JudgeDroppedFrames(6, 40, "spots smaller than dots.min_pixels", 5);
  EXPECT_EQ(some.level, Level::kWarn);
  EXPECT_NE(some.figure.find("main reason (5): spots smaller"), std::string::npos) << some.figure;
  EXPECT_EQ(JudgeDroppedFrames(9, 40, "r", 9).level, Level::kFail);

  EXPECT_EQ(JudgeReadingsLost(0, 0, 60000).level, Level::kPass);
  EXPECT_EQ(JudgeReadingsLost(6, 0, 60000).level, Level::kPass);  // 1e-4
  EXPECT_EQ(JudgeReadingsLost(30, 30, 60000).level, Level::kWarn);
  EXPECT_EQ(JudgeReadingsLost(0, 700, 60000).level, Level::kFail);
  const VerdictLine no_journal = JudgeReadingsLost(0, -1, 1000);
  EXPECT_EQ(no_journal.level, Level::kPass);
  EXPECT_NE(no_journal.figure.find("not recorded"), std::string::npos);
}

TEST(Verdict, HallResidualDeltaTAndClock) {
  const double floor[3] = {0.01, 0.01, 0.005};
  const double good[3] = {0.02, 0.025, 0.01};
  const double warn[3] = {0.02, 0.05, 0.01};
  const double bad[3] = {0.2, 0.03, 0.01};
  EXPECT_EQ(JudgeHallResidual(good, floor).level, Level::kPass);
  EXPECT_EQ(JudgeHallResidual(warn, floor).level, Level::kWarn);
  EXPECT_EQ(JudgeHallResidual(bad, floor).level, Level::kFail);
  const double zero[3] = {0, 0, 0};
  EXPECT_EQ(JudgeHallResidual(good, zero).level, Level::kFail);  // no floor: cannot pass

  EXPECT_EQ(JudgeDeltaT(0.5e-3, 0.1e-3, -0.01, 0.01).level, Level::kPass);
  EXPECT_EQ(JudgeDeltaT(0.5e-3, 0.5e-3, -0.01, 0.01).level, Level::kWarn);
  EXPECT_EQ(JudgeDeltaT(0.5e-3, 3e-3, -0.01, 0.01).level, Level::kFail);
  const VerdictLine bound = JudgeDeltaT(0.0099, 0.01e-3, -0.01, 0.01);
  EXPECT_EQ(bound.level, Level::kFail);
  EXPECT_NE(bound.figure.find("search bound"), std::string::npos);

  EXPECT_EQ(JudgeClock(0.4, 120, 0, 0).level, Level::kPass);
  EXPECT_EQ(JudgeClock(12, 120, 0, 0).level, Level::kWarn);
  EXPECT_EQ(JudgeClock(1, 120, 2, 1).level, Level::kWarn);
  EXPECT_EQ(JudgeClock(1, 100, 10, 0).level, Level::kFail);
  EXPECT_EQ(JudgeClock(80, 120, 0, 0).level, Level::kFail);
  EXPECT_EQ(JudgeClock(0, 0, 0, 0).level, Level::kFail);
}

TEST(Verdict, OverallIsTheWorstLine) {
  EXPECT_EQ(Overall({}), Level::kPass);
  EXPECT_EQ(Overall({JudgePlanes(10, 10), JudgePlanes(8, 10)}), Level::kWarn);
  EXPECT_EQ(Overall({JudgePlanes(8, 10), JudgePlanes(1, 10), JudgePlanes(10, 10)}), Level::kFail);
  EXPECT_STREQ(ToString(Level::kWarn), "warn");
}

}  // namespace
}  // namespace msmcal::report

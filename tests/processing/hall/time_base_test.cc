#include "processing/hall/time_base.h"

#include <gtest/gtest.h>

#include <cmath>

namespace msmcal::hall {
namespace {

std::vector<double> Edges(double offset_us, double ppm, double period, int n) {
  std::vector<double> e;
  for (int k = 0; k < n; ++k)
    e.push_back(std::llround(offset_us + 1e6 * (1 + ppm * 1e-6) * k * period));
  return e;
}

TEST(TimeBase, RecoversOffsetAndRate) {
  const auto edges = Edges(5'000'000.0, -42.0, 0.25, 200);
  const TimeBase tb = FitTimeBase(edges, 0.25);
  EXPECT_NEAR(tb.offset_us, 5'000'000.0, 1.0);
  EXPECT_NEAR(tb.RateErrorPpm(), -42.0, 0.05);
  EXPECT_EQ(tb.edges_used, 200);
  EXPECT_EQ(tb.edges_missing, 0);
  EXPECT_LT(tb.jitter_rms_us, 0.6);  // the 1 us quantisation
  EXPECT_NEAR(tb.GeneratorTime(edges[40]), 40 * 0.25, 1e-6);
  EXPECT_NEAR(tb.McuTime(tb.GeneratorTime(123456789)), 123456789.0, 1e-6);
}

TEST(TimeBase, RobustToMissingAndSpuriousEdges) {
  auto edges = Edges(1000.0, 80.0, 0.5, 100);
  edges.erase(edges.begin() + 30);                       // a missed edge
  edges.erase(edges.begin() + 60);                       // another
  edges.insert(edges.begin() + 10, edges[9] + 137'000);  // a glitch between two edges
  const TimeBase tb = FitTimeBase(edges, 0.5);
  EXPECT_EQ(tb.edges_rejected, 1);
  EXPECT_EQ(tb.edges_missing, 2);
  EXPECT_EQ(tb.edges_used, 98);
  EXPECT_NEAR(tb.RateErrorPpm(), 80.0, 0.05);
  EXPECT_NEAR(tb.offset_us, 1000.0, 1.0);
}

TEST(TimeBase, ClearErrors) {
  EXPECT_THROW(FitTimeBase({100}, 0.5), std::invalid_argument);
  // Edges 1 s apart while the pattern period says 0.5 s: every other edge is "missing", fine;
  // edges 0.7 s apart do not fit the grid at all.
  try {
    FitTimeBase(Edges(0, 0, 0.7, 50), 0.5);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("FitTimeBase"), std::string::npos);
  }
  TimeBaseOptions bad;
  bad.max_phase_error = 0.7;
  EXPECT_THROW(FitTimeBase(Edges(0, 0, 0.5, 10), 0.5, bad), std::invalid_argument);
}

}  // namespace
}  // namespace msmcal::hall

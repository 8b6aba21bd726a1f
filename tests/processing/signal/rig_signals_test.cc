#include "processing/signal/rig_signals.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace msmcal::signal {
namespace {

SineDrive Fast() { return {/*frequency_hz=*/1230.0, /*amplitude_vpp=*/2.0, 0.0, 0.0}; }
SineDrive Slow() { return {/*frequency_hz=*/30.0, /*amplitude_vpp=*/1.0, 0.0, 0.0}; }

TEST(PatternPeriodTest, GcdOfIntegerAndFractionalFrequencies) {
  EXPECT_DOUBLE_EQ(PatternPeriod(1230.0, 30.0), 1.0 / 30.0);
  EXPECT_DOUBLE_EQ(PatternPeriod(1000.5, 10.0), 2.0);          // gcd 0.5 Hz
  EXPECT_NEAR(PatternPeriod(1234.5, 27.1), 10.0, 1e-9);        // gcd 0.1 Hz
  EXPECT_NEAR(PatternPeriod(1234.5, 27.3), 10.0 / 3.0, 1e-9);  // gcd 0.3 Hz
  EXPECT_DOUBLE_EQ(PatternPeriod(7.0, 7.0), 1.0 / 7.0);
}

TEST(PatternPeriodTest, RejectsNonPositiveAndOffGrid) {
  EXPECT_THROW(PatternPeriod(0.0, 10.0), std::invalid_argument);
  EXPECT_THROW(PatternPeriod(10.0, -1.0), std::invalid_argument);
  try {
    PatternPeriod(1000.00001, 10.0);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fast.frequency_hz"), std::string::npos);
  }
}

TEST(ArbTimingTest, RespectsPointAndRateLimits) {
  TriggerDesignOptions o;
  // Long period: point-limited.
  ArbTiming a = ChooseArbTiming(10.0, o);
  EXPECT_EQ(a.points, o.max_points);
  EXPECT_DOUBLE_EQ(a.sample_rate_sps, 1e5);
  // Short period: rate-limited.
  ArbTiming b = ChooseArbTiming(1e-3, o);
  EXPECT_EQ(b.points, 160000);
  EXPECT_LE(b.sample_rate_sps, o.max_sample_rate_sps * (1 + 1e-12));
  EXPECT_NEAR(b.points * b.quantum_s, 1e-3, 1e-15);
  // Too short for 8 points at 160 MSa/s.
  EXPECT_THROW(ChooseArbTiming(1e-8, o), std::invalid_argument);
}

TEST(TriggerDesignTest, TriggersAreRisingSparseAndQuantised) {
  TriggerDesignOptions o;
  const TriggerDesign d = DesignTriggers(Fast(), Slow(), o);
  ASSERT_GT(d.times_s.size(), 5u);
  EXPECT_NEAR(d.pattern_period_s, 1.0 / 30.0, 1e-15);
  EXPECT_GE(d.arb.points, 8);
  EXPECT_LE(d.arb.points, o.max_points);
  EXPECT_LE(d.max_quantisation_error_s, 0.5 * d.arb.quantum_s + 1e-15);
  EXPECT_LE(d.duty, o.max_duty);
  const double pi = 3.14159265358979323846;
  for (size_t i = 0; i < d.times_s.size(); ++i) {
    const double t = d.times_s[i];
    EXPECT_GE(t, 0.0);
    EXPECT_LT(t, d.pattern_period_s);
    EXPECT_NEAR(t, d.sample_index[i] * d.arb.quantum_s, 1e-15);
    // Both sines rising (allowing one sample of quantisation at the boundary).
    const double slack = 2 * pi * 1230.0 * d.arb.quantum_s;
    EXPECT_GT(std::cos(2 * pi * 1230.0 * t), -slack) << i;
    EXPECT_GT(std::cos(2 * pi * 30.0 * t), -slack) << i;
    for (size_t k = 0; k < i; ++k) {
      const double dist = std::hypot(SineUnit(Fast(), t) - SineUnit(Fast(), d.times_s[k]),
                                     SineUnit(Slow(), t) - SineUnit(Slow(), d.times_s[k]));
      EXPECT_GE(dist, o.min_separation) << i << " " << k;
    }
    if (i > 0) {
      EXPECT_GT(d.sample_index[i], d.sample_index[i - 1] + d.pulse_samples);
    }
  }
}

TEST(TriggerDesignTest, ArbSamplesHaveOneRisingEdgePerTrigger) {
  TriggerDesignOptions o;
  o.pulse_width_s = 2e-6;
  const TriggerDesign d = DesignTriggers(Fast(), Slow(), o);
  const std::vector<int16_t> s = TriggerArbSamples(d);
  ASSERT_EQ(static_cast<int64_t>(s.size()), d.arb.points);
  std::vector<int64_t> edges;
  for (size_t k = 0; k < s.size(); ++k) {
    const int16_t prev = s[(k + s.size() - 1) % s.size()];
    if (prev < 0 && s[k] > 0) edges.push_back(static_cast<int64_t>(k));
  }
  EXPECT_EQ(edges, d.sample_index);
  int64_t high = 0;
  for (int16_t v : s) high += v > 0;
  EXPECT_EQ(high, static_cast<int64_t>(d.sample_index.size()) * d.pulse_samples);
}

TEST(TriggerDesignTest, DutyLimitIsRefusedNotClipped) {
  TriggerDesignOptions o;
  o.pulse_width_s = 1e-4;
  o.max_duty = 0.001;
  try {
    DesignTriggers(Fast(), Slow(), o);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_duty"), std::string::npos) << e.what();
  }
}

TEST(TriggerDesignTest, ValidateNamesField) {
  TriggerDesignOptions o;
  o.spacing = -1;
  EXPECT_NE(o.Validate().find("trigger.spacing = -1"), std::string::npos);
  o = {};
  o.max_points = 4;
  EXPECT_NE(o.Validate().find("trigger.max_points"), std::string::npos);
  EXPECT_TRUE(TriggerDesignOptions{}.Validate().empty());
}

TEST(ClockTest, RisingEdgeAtPhaseZeroOncePerPeriod) {
  const ClockDesign c = DesignClock(2.0);
  EXPECT_DOUBLE_EQ(c.frequency_hz, 0.5);
  EXPECT_DOUBLE_EQ(c.phase_deg, 0.0);
}

TEST(SineTest, ValueMatchesClosedForm) {
  SineDrive d{100.0, 4.0, 0.5, 90.0};
  EXPECT_NEAR(SineValue(d, 0.0), 2.5, 1e-12);
  EXPECT_NEAR(SineValue(d, 0.005), -1.5, 1e-12);
}

}  // namespace
}  // namespace msmcal::signal

#include "processing/signal/rig_signals.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "common/units.h"

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

// The trigger walk skips the stretches where a drive falls (FirstPossiblyRisingSample). The
// plain walk over every sample, kept here as the reference, must place exactly the same
// triggers for any drives: random frequencies on the 1 mHz grid, phases, spacings and sizes.
std::vector<int64_t> ReferenceTriggerSamples(const SineDrive& fast, const SineDrive& slow,
                                             const TriggerDesignOptions& o) {
  const double period = PatternPeriod(fast.frequency_hz, slow.frequency_hz);
  const ArbTiming arb = ChooseArbTiming(period, o);
  const int64_t n = arb.points;
  const double dt = arb.quantum_s;
  const int64_t pulse =
      std::max<int64_t>(1, static_cast<int64_t>(std::ceil(o.pulse_width_s / dt - 1e-9)));
  auto phase = [](const SineDrive& d, double t) {
    return 2.0 * 3.14159265358979323846 * d.frequency_hz * t + common::DegToRad(d.phase_deg);
  };
  auto rising = [&](double t) {
    return std::cos(phase(fast, t)) > 0.0 && std::cos(phase(slow, t)) > 0.0;
  };
  std::vector<double> sx, sy;
  std::vector<int64_t> out;
  double acc = 0.0, px = SineUnit(fast, 0.0), py = SineUnit(slow, 0.0);
  bool prev_rising = rising(0.0);
  int64_t last = -(1LL << 60);
  for (int64_t k = 1; k <= n; ++k) {
    const double t = static_cast<double>(k) * dt;
    const double x = SineUnit(fast, t), y = SineUnit(slow, t);
    const bool now_rising = rising(t);
    const double seg = std::hypot(x - px, y - py);
    if (prev_rising && now_rising && seg > 0.0) {
      if (acc + seg >= o.spacing) {
        const double t_ideal = t - dt + (o.spacing - acc) / seg * dt;
        acc = acc + seg - o.spacing;
        int64_t idx = static_cast<int64_t>(std::llround(t_ideal / dt));
        if (idx >= n) idx -= n;
        const double qx = SineUnit(fast, idx * dt), qy = SineUnit(slow, idx * dt);
        bool far = idx >= last + pulse + 1 && idx + pulse < n;
        for (size_t i = 0; far && i < sx.size(); ++i)
          far = std::hypot(qx - sx[i], qy - sy[i]) >= o.min_separation;
        if (far) {
          sx.push_back(qx);
          sy.push_back(qy);
          out.push_back(idx);
          last = idx;
          if (static_cast<int>(out.size()) >= o.max_triggers) break;
        }
      } else {
        acc += seg;
      }
    } else {
      acc = 0.0;
    }
    px = x;
    py = y;
    prev_rising = now_rising;
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(TriggerDesignTest, SkippingFallingStretchesPlacesTheSameTriggersAsTheFullWalk) {
  std::mt19937_64 rng(20261207);
  auto uniform = [&](double a, double b) { return std::uniform_real_distribution<>(a, b)(rng); };
  int designs = 0;
  for (int trial = 0; trial < 60; ++trial) {
    SineDrive fast, slow;
    fast.frequency_hz = std::round(uniform(50.0, 2000.0) * 1000.0) / 1000.0;
    slow.frequency_hz = std::round(uniform(0.5, 40.0) * (trial % 3 == 0 ? 1.0 : 1000.0)) /
                        (trial % 3 == 0 ? 1.0 : 1000.0);
    fast.phase_deg = trial % 4 == 0 ? 0.0 : uniform(-720.0, 720.0);
    slow.phase_deg = trial % 5 == 0 ? 90.0 : uniform(-720.0, 720.0);
    TriggerDesignOptions o;
    o.spacing = uniform(0.05, 0.6);
    o.min_separation = uniform(0.0, 0.2);
    o.max_triggers = trial % 2 == 0 ? 2000 : 20;
    o.max_points = trial % 3 == 0 ? 1'000'000 : 50'000;
    o.max_duty = 1.0;
    std::vector<int64_t> expected;
    try {
      expected = ReferenceTriggerSamples(fast, slow, o);
    } catch (const std::invalid_argument&) {
      continue;  // the pattern period needs more points than allowed: both refuse it
    }
    if (expected.empty()) {
      EXPECT_THROW(DesignTriggers(fast, slow, o), std::invalid_argument);
      continue;
    }
    const TriggerDesign d = DesignTriggers(fast, slow, o);
    EXPECT_EQ(d.sample_index, expected)
        << "fast " << fast.frequency_hz << " Hz " << fast.phase_deg << " deg, slow "
        << slow.frequency_hz << " Hz " << slow.phase_deg << " deg, spacing " << o.spacing;
    ++designs;
  }
  EXPECT_GE(designs, 40);  // the comparison ran on most of the draws
}

// Found by fuzz/rig_yaml: a pulse width of 1e13 s made the pulse's sample count overflow.
TEST(TriggerDesignTest, APulseAsLongAsThePeriodIsRefused) {
  SineDrive fast{205, 2, 0, 0}, slow{5, 4, 0, 0};
  TriggerDesignOptions o;
  for (double width : {0.2, 1.0, 1e13}) {
    o.pulse_width_s = width;
    try {
      (void)DesignTriggers(fast, slow, o);
      ADD_FAILURE() << "no error for pulse_width_s = " << width;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("pulse_width_s"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("pattern period (0.2 s)"), std::string::npos)
          << e.what();
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
  // Beyond what the instrument holds or plays (a fuzzed rig file asked for 60 M points: a 120 MB
  // waveform designed for 2 s before the instrument would refuse it).
  o = {};
  o.max_points = 60'020'003;
  EXPECT_NE(o.Validate().find("trigger.max_points = 60020003: must be <= 16000000"),
            std::string::npos)
      << o.Validate();
  o.max_points = 16'000'000;  // the 33520B with option MEM
  EXPECT_TRUE(o.Validate().empty()) << o.Validate();
  o.max_sample_rate_sps = 250e6;
  EXPECT_NE(o.Validate().find("trigger.max_sample_rate_sps = 2.5e+08: must be in (0, 1.6e+08]"),
            std::string::npos)
      << o.Validate();
  o.max_sample_rate_sps = std::nan("");
  EXPECT_NE(o.Validate().find("trigger.max_sample_rate_sps"), std::string::npos);
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

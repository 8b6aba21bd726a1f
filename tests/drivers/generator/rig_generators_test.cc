// The four rig signals on the two mock units: the mock's physical signals match the design, the
// unlocked slave is refused before any output, and every wire fault ends with outputs off.
#include "drivers/generator/rig_generators.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>

#include "common/units.h"
#include "test_rig.h"

namespace msmcal::gen {
namespace {

constexpr int64_t kT0Ns = 7'000'000'000;  // the fake generator clock while the rig starts

struct Rig {
  explicit Rig(bool reference_wired = true, int io_timeout_ms = 2000)
      : pair(Options(reference_wired), [this] { return clock_ns.load(); }),
        config(testing::RigConfigFor(pair, io_timeout_ms)) {}
  static sim::GeneratorPairOptions Options(bool reference_wired) {
    sim::GeneratorPairOptions o;
    o.reference_wired = reference_wired;
    return o;
  }
  void Open() {
    master = OpenKeysight33500(config.unit1);
    slave = OpenKeysight33500(config.unit2);
    rig = std::make_unique<RigGenerators>(*master, *slave);
  }
  bool AllOff() { return !pair.unit(1).AnyOutputOn() && !pair.unit(2).AnyOutputOn(); }

  std::atomic<int64_t> clock_ns{kT0Ns};
  sim::MockGeneratorPair pair;
  RigGeneratorConfig config;
  std::unique_ptr<FunctionGenerator> master, slave;
  std::unique_ptr<RigGenerators> rig;
};

TEST(RigGeneratorsTest, MockSignalsMatchTheDesign) {
  Rig r;
  r.config.signals.fast.phase_deg = -45.0;  // phases must survive the triggered start
  r.config.signals.slow.phase_deg = 30.0;
  ASSERT_EQ(r.config.Validate(), "");
  const RigSignalPlan plan = PlanRigSignals(r.config.signals);
  r.Open();
  r.rig->Apply(plan);
  r.rig->VerifyLock();

  const double period = plan.trigger.pattern_period_s;
  const auto fast = r.pair.unit(1).Signal(1), slow = r.pair.unit(1).Signal(2);
  const auto laser = r.pair.unit(2).Signal(1), clock = r.pair.unit(2).Signal(2);
  for (const auto* c : {&fast, &slow, &laser, &clock}) {
    EXPECT_TRUE(c->output_on);
    EXPECT_TRUE(c->running);
    EXPECT_EQ(c->start_time_ns, kT0Ns);  // one start trigger for all four signals
  }
  EXPECT_EQ(r.pair.unit(2).ReferenceSourceCurrent(), "EXT");
  EXPECT_DOUBLE_EQ(fast.frequency_hz, r.config.signals.fast.frequency_hz);
  EXPECT_DOUBLE_EQ(slow.frequency_hz, r.config.signals.slow.frequency_hz);
  EXPECT_DOUBLE_EQ(fast.amplitude_vpp, r.config.signals.fast.amplitude_vpp);
  EXPECT_DOUBLE_EQ(fast.phase_deg, r.config.signals.fast.phase_deg);
  EXPECT_DOUBLE_EQ(fast.burst_phase_deg, r.config.signals.fast.phase_deg);
  EXPECT_DOUBLE_EQ(slow.burst_phase_deg, r.config.signals.slow.phase_deg);
  EXPECT_EQ(clock.function, sim::Function::kSquare);
  EXPECT_NEAR(clock.frequency_hz, 1.0 / period, 1e-9);
  EXPECT_EQ(laser.function, sim::Function::kArb);
  ASSERT_TRUE(laser.arb_samples);
  EXPECT_EQ(static_cast<int64_t>(laser.arb_samples->size()), plan.trigger.arb.points);
  EXPECT_NEAR(laser.arb_sample_rate_sps / laser.arb_samples->size(), 1.0 / period, 1e-9);

  // Rising edges of the laser trigger output over one period, sampled at the sample centres.
  const double q = plan.trigger.arb.quantum_s;
  const int64_t n = plan.trigger.arb.points;
  std::vector<double> edges_s;
  double prev = r.pair.unit(2).SignalAt(1, kT0Ns + static_cast<int64_t>((n - 0.5) * q * 1e9));
  for (int64_t k = 0; k < n; ++k) {
    const double v = r.pair.unit(2).SignalAt(1, kT0Ns + static_cast<int64_t>((k + 0.5) * q * 1e9));
    if (prev < 2.5 && v > 2.5) edges_s.push_back(k * q);
    prev = v;
  }
  ASSERT_EQ(edges_s.size(), plan.trigger.ideal_times_s.size());
  const double pi = 3.14159265358979323846;
  for (size_t j = 0; j < edges_s.size(); ++j) {
    // Within the sample-clock quantum of the ideal design time.
    EXPECT_LE(std::abs(edges_s[j] - plan.trigger.ideal_times_s[j]), 0.5 * q + 1e-12) << j;
    // The drives at the trigger: what the design predicted, both rising.
    const int64_t t_ns = kT0Ns + static_cast<int64_t>(std::llround(edges_s[j] * 1e9));
    EXPECT_NEAR(r.pair.unit(1).SignalAt(1, t_ns),
                signal::SineValue(r.config.signals.fast, edges_s[j]), 1e-5);  // 0.5 ns rounding
    EXPECT_NEAR(r.pair.unit(1).SignalAt(2, t_ns),
                signal::SineValue(r.config.signals.slow, edges_s[j]), 1e-5);
    const double slack = 2 * pi * fast.frequency_hz * q;
    EXPECT_GT(std::cos(2 * pi * fast.frequency_hz * edges_s[j] + common::DegToRad(fast.phase_deg)),
              -slack);
    EXPECT_GT(std::cos(2 * pi * slow.frequency_hz * edges_s[j] + common::DegToRad(slow.phase_deg)),
              -slack);
  }
  // Clock: rising edge at pattern phase 0 of every period.
  const int64_t period_ns = static_cast<int64_t>(std::llround(period * 1e9));
  for (int64_t m = 1; m <= 3; ++m) {
    EXPECT_GT(r.pair.unit(2).SignalAt(2, kT0Ns + m * period_ns + 1000), 3.0);
    EXPECT_LT(r.pair.unit(2).SignalAt(2, kT0Ns + m * period_ns - 1000), 0.3);
  }
  EXPECT_TRUE(r.rig->SafeState());
  EXPECT_TRUE(r.AllOff());
}

// Per-frame signals (docs/lab-path.md): drives started with their outputs off, then switched, and
// the laser pattern replaced, all without a re-arm: every channel keeps the start trigger's time
// base, the laser plays the new samples.
TEST(RigGeneratorsTest, DrivesSwitchAndLaserPatternChangeKeepTheTimeBase) {
  Rig r;
  ASSERT_EQ(r.config.Validate(), "");
  RigSignalPlan plan = PlanRigSignals(r.config.signals);
  r.Open();
  r.rig->Apply(plan, /*fast_on=*/false, /*slow_on=*/false);
  EXPECT_FALSE(r.pair.unit(1).Signal(1).output_on);
  EXPECT_FALSE(r.pair.unit(1).Signal(2).output_on);
  EXPECT_TRUE(r.pair.unit(1).Signal(1).running);  // started by the trigger all the same
  EXPECT_TRUE(r.pair.unit(2).Signal(1).output_on);
  EXPECT_TRUE(r.pair.unit(2).Signal(2).output_on);

  r.clock_ns += 3'000'000'000;  // later, generator time 3 s
  r.rig->SetDrives(true, false);
  EXPECT_TRUE(r.pair.unit(1).Signal(1).output_on);
  EXPECT_FALSE(r.pair.unit(1).Signal(2).output_on);
  // One trigger only: the first of the design.
  ChannelSetup laser = plan.unit2_ch1;
  std::fill(laser.arb_samples.begin(), laser.arb_samples.end(), int16_t{-32767});
  const int64_t index = plan.trigger.sample_index.front();
  for (int64_t k = 0; k < plan.trigger.pulse_samples; ++k)
    laser.arb_samples[static_cast<size_t>(index + k)] = 32767;
  r.rig->ReplaceLaserArb(laser);
  const auto played = r.pair.unit(2).Signal(1);
  ASSERT_TRUE(played.arb_samples);
  EXPECT_EQ(*played.arb_samples, laser.arb_samples);
  EXPECT_TRUE(played.running);
  for (const auto& c :
       {r.pair.unit(1).Signal(1), r.pair.unit(1).Signal(2), played, r.pair.unit(2).Signal(2)})
    EXPECT_EQ(c.start_time_ns, kT0Ns) << "a channel lost the common start";
  r.rig->SetDrives(false, false);
  EXPECT_FALSE(r.pair.unit(1).AnyOutputOn());
  EXPECT_TRUE(r.rig->SafeState());
  EXPECT_TRUE(r.AllOff());
}

TEST(RigGeneratorsTest, UnlockedSlaveIsRefusedBeforeAnyOutput) {
  Rig r(/*reference_wired=*/false);
  r.Open();
  try {
    r.rig->Apply(PlanRigSignals(r.config.signals));
    FAIL();
  } catch (const GeneratorError& e) {
    EXPECT_EQ(e.kind(), GeneratorError::Kind::kLock);
    EXPECT_NE(std::string(e.what()).find("not locked to the external 10 MHz"), std::string::npos);
  }
  EXPECT_TRUE(r.AllOff());
  EXPECT_EQ(r.pair.unit(2).Signal(1).function, sim::Function::kSin);  // never configured
  // Wiring fixed: the lock check passes.
  r.pair.SetReferenceWired(true);
  r.rig->Apply(PlanRigSignals(r.config.signals));
  // The cable comes off before recording: refused, outputs off.
  r.pair.SetReferenceWired(false);
  EXPECT_THROW(r.rig->VerifyLock(), GeneratorError);
  EXPECT_TRUE(r.AllOff());
}

struct FaultCase {
  sim::FaultKind kind;
  common::StatusCode expected;
};

class RigFaultTest : public ::testing::TestWithParam<FaultCase> {};

TEST_P(RigFaultTest, FaultAfterOutputsOnEndsInTypedErrorAndOutputsOff) {
  Rig r(/*reference_wired=*/true, /*io_timeout_ms=*/300);
  r.Open();
  // Master's *OPC? replies: Reset, SetReference, then Trigger (after all outputs are on).
  r.pair.server(1).InjectFault({GetParam().kind, "*OPC?", /*skip=*/2});
  try {
    r.rig->Apply(PlanRigSignals(r.config.signals));
    FAIL();
  } catch (const GeneratorError& e) {  // the unit's Status, as the session's exception
    EXPECT_EQ(e.kind(), GeneratorError::Kind::kLink) << e.what();
    EXPECT_EQ(e.code(), GetParam().expected) << e.what();
    EXPECT_NE(std::string(e.what()).find("*OPC?"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(r.AllOff());
  EXPECT_GE(r.pair.server(1).ConnectionsAccepted(), 2u);  // safe state reconnected
  r.pair.server(1).ReleaseDelayedReplies();
}

INSTANTIATE_TEST_SUITE_P(
    Faults, RigFaultTest,
    ::testing::Values(FaultCase{sim::FaultKind::kDelayReply, common::StatusCode::kTimeout},
                      FaultCase{sim::FaultKind::kDropMidReply, common::StatusCode::kUnavailable},
                      FaultCase{sim::FaultKind::kGarbageReply, common::StatusCode::kProtocol}));

TEST(RigGeneratorsTest, DriverRefusesLimitEvenIfConfigWasNotValidated) {
  Rig r;
  r.config.signals.slow.amplitude_vpp = 5.5;  // unit1.ch2 max_vpp 5.0
  r.Open();
  try {
    r.rig->Apply(PlanRigSignals(r.config.signals));
    FAIL();
  } catch (const GeneratorError& e) {
    EXPECT_EQ(e.kind(), GeneratorError::Kind::kLimit);
    EXPECT_STREQ(
        e.what(),
        "refused: unit1.ch2 (slow_coil): amplitude_vpp = 5.5 outside the limit [0, 5] Vpp");
  }
  EXPECT_TRUE(r.AllOff());
}

}  // namespace
}  // namespace msmcal::gen

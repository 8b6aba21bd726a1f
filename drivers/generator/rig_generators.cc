#include "drivers/generator/rig_generators.h"

#include <spdlog/spdlog.h>

namespace msmcal::gen {

RigSignalPlan PlanRigSignals(const RigSignalsConfig& c) {
  RigSignalPlan p;
  p.trigger = signal::DesignTriggers(c.fast, c.slow, c.trigger);
  p.clock = signal::DesignClock(p.trigger.pattern_period_s);

  auto sine = [&](const signal::SineDrive& d) {
    ChannelSetup s;
    s.waveform = Waveform::kSin;
    s.frequency_hz = d.frequency_hz;
    s.amplitude_vpp = d.amplitude_vpp;
    s.offset_v = d.offset_v;
    s.phase_deg = d.phase_deg;
    s.load_ohm = c.coil_load_ohm;
    return s;
  };
  p.unit1_ch1 = sine(c.fast);
  p.unit1_ch2 = sine(c.slow);

  ChannelSetup& laser = p.unit2_ch1;
  laser.waveform = Waveform::kArb;
  laser.arb_name = "MSMTRIG";
  laser.arb_samples = signal::TriggerArbSamples(p.trigger);
  laser.arb_sample_rate_sps = p.trigger.arb.sample_rate_sps;
  laser.frequency_hz = 1.0 / p.trigger.pattern_period_s;
  laser.amplitude_vpp = c.laser.high_v - c.laser.low_v;
  laser.offset_v = 0.5 * (c.laser.high_v + c.laser.low_v);
  laser.load_ohm = c.laser.load_ohm;

  ChannelSetup& clock = p.unit2_ch2;
  clock.waveform = Waveform::kSquare;
  clock.frequency_hz = p.clock.frequency_hz;
  clock.square_duty_percent = p.clock.duty_percent;
  clock.phase_deg = p.clock.phase_deg;
  clock.amplitude_vpp = c.clock.high_v - c.clock.low_v;
  clock.offset_v = 0.5 * (c.clock.high_v + c.clock.low_v);
  clock.load_ohm = c.clock.load_ohm;
  return p;
}

RigGenerators::RigGenerators(FunctionGenerator& master, FunctionGenerator& slave)
    : master_(master), slave_(slave) {}

namespace {

// A unit's failed Status as the session's exception.
void Must(const common::Status& s) {
  if (!s) throw GeneratorError(s);
}

}  // namespace

template <typename F>
void RigGenerators::Guarded(F&& f) {
  try {
    f();
  } catch (...) {
    if (!SafeState()) spdlog::error("safe state not confirmed by every generator");
    throw;
  }
}

void RigGenerators::VerifyLock() {
  Guarded([&] {
    const common::Result<bool> locked = slave_.ReferenceLocked();
    Must(locked.ok() ? common::Status::Ok() : locked.status());
    if (!*locked) {
      throw GeneratorError(GeneratorError::Kind::kLock,
                           "'" + slave_.name() +
                               "' is not locked to the external 10 MHz reference from '" +
                               master_.name() + "' (check the 10 MHz cable); refusing to run");
    }
  });
}

void RigGenerators::Apply(const RigSignalPlan& plan, bool fast_on, bool slow_on) {
  Guarded([&] {
    Must(master_.Reset());
    Must(slave_.Reset());
    Must(master_.SetReference(ReferenceSource::kInternal));
    Must(slave_.SetReference(ReferenceSource::kExternal));
    VerifyLock();
    Must(master_.ConfigureChannel(1, plan.unit1_ch1));
    Must(master_.ConfigureChannel(2, plan.unit1_ch2));
    Must(slave_.ConfigureChannel(1, plan.unit2_ch1));
    Must(slave_.ConfigureChannel(2, plan.unit2_ch2));
    Must(master_.ArmStart(StartTrigger::kBus, /*trigger_out=*/true));
    Must(slave_.ArmStart(StartTrigger::kExternal, /*trigger_out=*/false));
    if (fast_on) Must(master_.SetOutput(1, true));
    if (slow_on) Must(master_.SetOutput(2, true));
    for (int c = 1; c <= 2; ++c) Must(slave_.SetOutput(c, true));
    Must(master_.Trigger());
    VerifyLock();
  });
}

void RigGenerators::SetDrives(bool fast_on, bool slow_on) {
  Guarded([&] {
    Must(master_.SetOutput(1, fast_on));
    Must(master_.SetOutput(2, slow_on));
  });
}

void RigGenerators::ReplaceLaserArb(const ChannelSetup& laser) {
  Guarded([&] { Must(slave_.ReplaceArb(1, laser)); });
}

bool RigGenerators::SafeState() noexcept {
  const bool a = master_.SafeState();
  const bool b = slave_.SafeState();
  return a && b;
}

}  // namespace msmcal::gen

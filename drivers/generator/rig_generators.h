#pragma once
// The four phase-locked rig signals on the two generators (paper Sec. III-E):
//   unit 1 ch1: fast-axis sine, ch2: slow-axis sine (master: internal reference, bus trigger,
//   trigger out); unit 2 ch1: sparse laser trigger arb, ch2: clock square with its rising edge at
//   pattern phase 0 (slave: external 10 MHz reference, external trigger).

#include <functional>
#include <string>

#include "drivers/generator/function_generator.h"
#include "drivers/generator/rig_config.h"
#include "processing/signal/rig_signals.h"

namespace msmcal::gen {

struct RigSignalPlan {
  signal::TriggerDesign trigger;
  signal::ClockDesign clock;
  ChannelSetup unit1_ch1, unit1_ch2, unit2_ch1, unit2_ch2;
};

// Pure: designs the four channel setups from the configuration. Throws std::invalid_argument
// (from the signal design) when the design violates a limit.
RigSignalPlan PlanRigSignals(const RigSignalsConfig& config);

// Applies a plan to the master and slave units. A unit's failed Status becomes GeneratorError
// (its kind from the Status's code); any failure runs the safe state on both units before the
// exception propagates.
class RigGenerators {
 public:
  RigGenerators(FunctionGenerator& master, FunctionGenerator& slave);

  // Reset, reference (slave locked to the master's 10 MHz, verified), channels, arm, outputs
  // on, start trigger, final lock check. Throws GeneratorError(kLock) when the slave is not
  // locked, before any output is switched on. The drive outputs (unit 1 ch1 fast, ch2 slow) are
  // switched on only as `fast_on` / `slow_on` say; their sines run (the start trigger starts all
  // four channels) either way, so that SetDrives later keeps the common time base.
  void Apply(const RigSignalPlan& plan, bool fast_on = true, bool slow_on = true);
  // Drive outputs on/off (OUTPut only: the sines keep running from the start trigger, so the
  // drives, the laser arb and the clock stay phase-locked). Safe state on failure.
  void SetDrives(bool fast_on, bool slow_on);
  // A new laser pattern on unit 2 ch1 (FunctionGenerator::ReplaceArb: same name, points and
  // rate as the applied plan's; no re-arm, so the clock and the drives are not disturbed).
  // Safe state on failure.
  void ReplaceLaserArb(const ChannelSetup& laser);
  // Throws GeneratorError(kLock) unless the slave runs on the external reference. Call before
  // any recording starts.
  void VerifyLock();
  // Outputs off on both units; true when both confirmed.
  bool SafeState() noexcept;

 private:
  template <typename F>
  void Guarded(F&& f);
  FunctionGenerator& master_;
  FunctionGenerator& slave_;
};

}  // namespace msmcal::gen

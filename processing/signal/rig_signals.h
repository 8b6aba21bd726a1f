#pragma once
// Rig signal design (paper Sec. III-E), pure math: the pattern period of the two sine drives, the
// sparse laser trigger times, the trigger arbitrary waveform and the clock.
//
// Time base: generator time t in seconds from pattern start (t = 0 when the start trigger fires).
// Signal space: each sine drive normalised to [-1, 1], s(t) = (sin(w_f t + p_f), sin(w_s t + p_s));
// the mirror angles are nearly linear in the drive currents, so distances in signal space predict
// dot distances in the image up to a per-axis scale.

#include <cstdint>
#include <string>
#include <vector>

namespace msmcal::signal {

// One sine output: v(t) = offset_v + amplitude_vpp / 2 * sin(2 pi frequency_hz t + phase).
struct SineDrive {
  double frequency_hz = 0.0;
  double amplitude_vpp = 0.0;
  double offset_v = 0.0;
  double phase_deg = 0.0;
};

// Voltage of `drive` at generator time t_s.
double SineValue(const SineDrive& drive, double t_s);
// Normalised signal-space coordinate sin(2 pi f t + phase) in [-1, 1].
double SineUnit(const SineDrive& drive, double t_s);

// Pattern period T = 1 / gcd(f_fast, f_slow). Frequencies must be integer multiples of
// resolution_hz (within 1e-9 relative); throws std::invalid_argument naming the value otherwise,
// or when a frequency is not positive.
double PatternPeriod(double f_fast_hz, double f_slow_hz, double resolution_hz = 1e-3);

struct TriggerDesignOptions {
  // Signal-space arc length between consecutive triggers along the rising-rising part of the
  // trajectory (normalised units, each axis spans [-1, 1]).
  double spacing = 0.25;
  // Minimum signal-space distance between the predicted dots of any two triggers.
  double min_separation = 0.15;
  // Upper bound on the number of triggers per pattern period.
  int max_triggers = 2000;
  // Arbitrary waveform limits of the generator (33520B: 8 .. 1 M points standard memory,
  // up to 160 MSa/s).
  int64_t min_points = 8;
  int64_t max_points = 1'000'000;
  double max_sample_rate_sps = 160e6;
  // Laser trigger pulse high time (rounded up to whole samples, at least one sample).
  double pulse_width_s = 1e-6;
  // Highest allowed fraction of the period the trigger output is high.
  double max_duty = 0.01;

  // Empty when valid; otherwise names the field, its value and the violated constraint.
  std::string Validate() const;
};

// Arbitrary waveform timing: `points` samples played at `sample_rate_sps` make exactly one
// pattern period. quantum_s = 1 / sample_rate_sps.
struct ArbTiming {
  double sample_rate_sps = 0.0;
  int64_t points = 0;
  double quantum_s = 0.0;
};

// Largest point count within [min_points, max_points] whose sample rate does not exceed
// max_sample_rate_sps (more points = finer trigger timing). Throws std::invalid_argument when the
// period is so short that min_points would exceed the sample-rate limit.
ArbTiming ChooseArbTiming(double period_s, const TriggerDesignOptions& options);

struct TriggerDesign {
  double pattern_period_s = 0.0;
  ArbTiming arb;
  // Ideal (continuous) trigger times from the design rule, seconds in [0, T).
  std::vector<double> ideal_times_s;
  // Trigger sample indices in the arb and the times they realise (index / sample rate).
  std::vector<int64_t> sample_index;
  std::vector<double> times_s;
  int64_t pulse_samples = 1;
  double duty = 0.0;
  // max |times_s - ideal_times_s|, at most half a sample quantum.
  double max_quantisation_error_s = 0.0;
};

// Designs the sparse trigger table. Throws std::invalid_argument when the options are invalid
// or the design violates a limit (duty, no triggers found); the message names the constraint.
TriggerDesign DesignTriggers(const SineDrive& fast, const SineDrive& slow,
                             const TriggerDesignOptions& options);

// DAC samples of the trigger arb: -32767 (low) everywhere, +32767 for pulse_samples samples
// starting at each trigger index. Size arb.points.
std::vector<int16_t> TriggerArbSamples(const TriggerDesign& design);

// Clock for the Hall MCU: a square wave at 1/T whose rising edge is at pattern phase 0
// (a square of phase 0 is high on [0, duty) of each cycle).
struct ClockDesign {
  double frequency_hz = 0.0;
  double duty_percent = 50.0;
  double phase_deg = 0.0;
};
ClockDesign DesignClock(double pattern_period_s);

}  // namespace msmcal::signal

#include "processing/signal/rig_signals.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "common/number_format.h"
#include "common/units.h"

namespace msmcal::signal {
namespace {

constexpr double kPi = 3.14159265358979323846;

double Phase(const SineDrive& d, double t_s) {
  return 2.0 * kPi * d.frequency_hz * t_s + common::DegToRad(d.phase_deg);
}

std::string Fmt(double v) { return common::FormatSignificant(v, 12); }

int64_t ToSteps(const char* name, double f_hz, double resolution_hz) {
  if (!(f_hz > 0.0) || !std::isfinite(f_hz)) {
    throw std::invalid_argument(std::string(name) + " = " + Fmt(f_hz) + ": must be > 0");
  }
  const double steps = f_hz / resolution_hz;
  const double rounded = std::round(steps);
  if (std::abs(steps - rounded) > 1e-9 * std::max(1.0, rounded) || rounded > 9e15) {
    throw std::invalid_argument(std::string(name) + " = " + Fmt(f_hz) +
                                ": must be an integer multiple of the frequency resolution " +
                                Fmt(resolution_hz) + " Hz");
  }
  return static_cast<int64_t>(rounded);
}

// A lower bound on the first sample index after `k` at which both drives rise (cos of the phase
// > 0), for a sample `k` at which at least one does not: each drive that falls at k first has to
// reach phase 3 pi / 2 (mod 2 pi) again. Two samples of margin cover the rounding of the phase
// (about 1e-9 rad against a step of at least 2 pi / max_points).
int64_t FirstPossiblyRisingSample(const SineDrive& fast, const SineDrive& slow, int64_t k,
                                  double dt) {
  const double t = static_cast<double>(k) * dt;
  double wait_s = 0.0;
  for (const SineDrive* d : {&fast, &slow}) {
    const double phase = Phase(*d, t);
    if (std::cos(phase) > 0.0) continue;
    double u = std::fmod(phase, 2.0 * kPi);
    if (u < 0.0) u += 2.0 * kPi;
    const double to_rise = std::max(0.0, 1.5 * kPi - u);
    wait_s = std::max(wait_s, to_rise / (2.0 * kPi * d->frequency_hz));
  }
  const double steps = std::floor(wait_s / dt) - 2.0;
  if (!(steps > 1.0)) return k + 1;
  return k + static_cast<int64_t>(std::min(steps, 9e15));
}

}  // namespace

double SineUnit(const SineDrive& drive, double t_s) { return std::sin(Phase(drive, t_s)); }

double SineValue(const SineDrive& drive, double t_s) {
  return drive.offset_v + 0.5 * drive.amplitude_vpp * SineUnit(drive, t_s);
}

double PatternPeriod(double f_fast_hz, double f_slow_hz, double resolution_hz) {
  if (!(resolution_hz > 0.0)) {
    throw std::invalid_argument("resolution_hz = " + Fmt(resolution_hz) + ": must be > 0");
  }
  const int64_t a = ToSteps("fast.frequency_hz", f_fast_hz, resolution_hz);
  const int64_t b = ToSteps("slow.frequency_hz", f_slow_hz, resolution_hz);
  const int64_t g = std::gcd(a, b);
  return 1.0 / (static_cast<double>(g) * resolution_hz);
}

namespace {
// What the 33520B's arbitrary waveforms allow at most (16 M points with option MEM, 1 M without;
// its sample rate), as the mock instrument models them.
constexpr int64_t kMaxArbPoints = 16'000'000;
constexpr double kMaxArbSampleRateSps = 160e6;
}  // namespace

std::string TriggerDesignOptions::Validate() const {
  std::ostringstream os;
  if (!(spacing > 0.0)) {
    os << "trigger.spacing = " << spacing << ": must be > 0";
  } else if (!(min_separation >= 0.0)) {
    os << "trigger.min_separation = " << min_separation << ": must be >= 0";
  } else if (max_triggers < 1) {
    os << "trigger.max_triggers = " << max_triggers << ": must be >= 1";
  } else if (min_points < 8) {
    os << "trigger.min_points = " << min_points << ": must be >= 8 (instrument minimum)";
  } else if (max_points < min_points) {
    os << "trigger.max_points = " << max_points << ": must be >= min_points (" << min_points << ")";
  } else if (max_points > kMaxArbPoints) {
    os << "trigger.max_points = " << max_points << ": must be <= " << kMaxArbPoints
       << " (the 33520B's arbitrary waveform memory with option MEM; 1 000 000 without)";
  } else if (!(max_sample_rate_sps > 0.0) || max_sample_rate_sps > kMaxArbSampleRateSps) {
    os << "trigger.max_sample_rate_sps = " << max_sample_rate_sps << ": must be in (0, "
       << kMaxArbSampleRateSps << "] (the 33520B's arbitrary waveform sample rate)";
  } else if (!(pulse_width_s > 0.0)) {
    os << "trigger.pulse_width_s = " << pulse_width_s << ": must be > 0";
  } else if (!(max_duty > 0.0 && max_duty <= 1.0)) {
    os << "trigger.max_duty = " << max_duty << ": must be in (0, 1]";
  }
  return os.str();
}

ArbTiming ChooseArbTiming(double period_s, const TriggerDesignOptions& options) {
  if (!(period_s > 0.0) || !std::isfinite(period_s)) {
    throw std::invalid_argument("pattern period = " + Fmt(period_s) + " s: must be > 0");
  }
  const double by_rate = std::floor(period_s * options.max_sample_rate_sps * (1.0 + 1e-12));
  const int64_t points =
      static_cast<int64_t>(std::min(static_cast<double>(options.max_points), by_rate));
  if (points < options.min_points) {
    throw std::invalid_argument("pattern period = " + Fmt(period_s) + " s: needs " +
                                Fmt(options.min_points * 1.0) + " points at most " +
                                Fmt(options.max_sample_rate_sps) +
                                " Sa/s, i.e. a period >= min_points / max_sample_rate_sps");
  }
  ArbTiming t;
  t.points = points;
  t.sample_rate_sps = static_cast<double>(points) / period_s;
  t.quantum_s = 1.0 / t.sample_rate_sps;
  return t;
}

TriggerDesign DesignTriggers(const SineDrive& fast, const SineDrive& slow,
                             const TriggerDesignOptions& options) {
  if (const std::string err = options.Validate(); !err.empty()) {
    throw std::invalid_argument(err);
  }
  TriggerDesign design;
  design.pattern_period_s = PatternPeriod(fast.frequency_hz, slow.frequency_hz);
  design.arb = ChooseArbTiming(design.pattern_period_s, options);
  const int64_t n = design.arb.points;
  const double dt = design.arb.quantum_s;
  // A pulse as long as the period is no pulse (and its sample count may not fit an integer:
  // fuzz/rig_yaml, pulse_width_s 1e13 s).
  const double pulse = std::ceil(options.pulse_width_s / dt - 1e-9);
  if (!(pulse < static_cast<double>(n))) {
    throw std::invalid_argument("trigger design: pulse_width_s = " + Fmt(options.pulse_width_s) +
                                " s is not shorter than the pattern period (" +
                                Fmt(design.pattern_period_s) + " s)");
  }
  design.pulse_samples = std::max<int64_t>(1, static_cast<int64_t>(pulse));

  // Walk the sample grid; accumulate signal-space arc length while both sines rise. Both sines
  // and the rising test at one sample: one sincos per drive (the walk's hot spot).
  auto at = [&](double t, double* x, double* y) {
    double cx = 0.0, cy = 0.0;
    ::sincos(Phase(fast, t), x, &cx);
    ::sincos(Phase(slow, t), y, &cy);
    return cx > 0.0 && cy > 0.0;
  };
  std::vector<double> sx, sy;  // accepted dots in signal space
  double acc = 0.0;
  double px = 0.0, py = 0.0;
  bool prev_rising = at(0.0, &px, &py);
  int64_t last_index = -(1LL << 60);
  for (int64_t k = 1; k <= n; ++k) {
    if (!prev_rising) {
      // Nothing happens until both drives rise again: jump to just before the first sample
      // where they can (the walk's state there is the same as after stepping through).
      const int64_t next = FirstPossiblyRisingSample(fast, slow, k - 1, dt);
      if (next > n) break;
      if (next > k) {
        k = next;
        prev_rising = at(static_cast<double>(k - 1) * dt, &px, &py);
      }
    }
    const double t = static_cast<double>(k) * dt;
    double x = 0.0, y = 0.0;
    const bool now_rising = at(t, &x, &y);
    const double seg = std::hypot(x - px, y - py);
    if (prev_rising && now_rising && seg > 0.0) {
      if (acc + seg >= options.spacing) {
        // Ideal crossing by linear interpolation within the step, then the nearest sample.
        const double frac = (options.spacing - acc) / seg;
        const double t_ideal = t - dt + frac * dt;
        acc = acc + seg - options.spacing;
        int64_t idx = static_cast<int64_t>(std::llround(t_ideal / dt));
        if (idx >= n) idx -= n;  // wraps to the next period's start
        const double qx = SineUnit(fast, idx * dt), qy = SineUnit(slow, idx * dt);
        bool far = idx >= last_index + design.pulse_samples + 1 &&
                   idx + design.pulse_samples < n;  // leave a falling edge before the wrap
        for (size_t i = 0; far && i < sx.size(); ++i) {
          far = std::hypot(qx - sx[i], qy - sy[i]) >= options.min_separation;
        }
        if (far) {
          sx.push_back(qx);
          sy.push_back(qy);
          design.ideal_times_s.push_back(t_ideal);
          design.sample_index.push_back(idx);
          design.times_s.push_back(static_cast<double>(idx) * dt);
          last_index = idx;
          if (static_cast<int>(design.sample_index.size()) >= options.max_triggers) break;
        }
      } else {
        acc += seg;
      }
    } else {
      acc = 0.0;  // a new rising-rising segment starts its own spacing count
    }
    px = x;
    py = y;
    prev_rising = now_rising;
  }
  if (design.sample_index.empty()) {
    throw std::invalid_argument(
        "trigger design: no trigger satisfies spacing = " + Fmt(options.spacing) +
        " and min_separation = " + Fmt(options.min_separation));
  }
  // Order by sample index (a wrapped index lands first).
  std::vector<size_t> order(design.sample_index.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return design.sample_index[a] < design.sample_index[b]; });
  TriggerDesign sorted = design;
  for (size_t i = 0; i < order.size(); ++i) {
    sorted.ideal_times_s[i] = design.ideal_times_s[order[i]];
    sorted.sample_index[i] = design.sample_index[order[i]];
    sorted.times_s[i] = design.times_s[order[i]];
  }
  design = std::move(sorted);
  for (size_t i = 0; i < design.times_s.size(); ++i) {
    double e = std::abs(design.times_s[i] - design.ideal_times_s[i]);
    e = std::min(e, std::abs(e - design.pattern_period_s));  // wrapped
    design.max_quantisation_error_s = std::max(design.max_quantisation_error_s, e);
  }
  design.duty = static_cast<double>(design.sample_index.size() * design.pulse_samples) /
                static_cast<double>(n);
  if (design.duty > options.max_duty) {
    throw std::invalid_argument("trigger design: duty = " + Fmt(design.duty) +
                                " exceeds trigger.max_duty = " + Fmt(options.max_duty) +
                                " (increase spacing or shorten pulse_width_s)");
  }
  return design;
}

std::vector<int16_t> TriggerArbSamples(const TriggerDesign& design) {
  std::vector<int16_t> samples(static_cast<size_t>(design.arb.points), -32767);
  for (int64_t idx : design.sample_index) {
    for (int64_t k = 0; k < design.pulse_samples && idx + k < design.arb.points; ++k) {
      samples[static_cast<size_t>(idx + k)] = 32767;
    }
  }
  return samples;
}

ClockDesign DesignClock(double pattern_period_s) {
  if (!(pattern_period_s > 0.0)) {
    throw std::invalid_argument("pattern period = " + Fmt(pattern_period_s) + " s: must be > 0");
  }
  ClockDesign c;
  c.frequency_hz = 1.0 / pattern_period_s;
  return c;
}

}  // namespace msmcal::signal

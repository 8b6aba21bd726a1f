#pragma once
// Mapping MCU time to generator time through the clock edges (MSM paper Sec. V-B, method.md).
//
// Generator 2's clock has a rising edge at every pattern start, t_k = k T (generator time,
// seconds from the first recorded pattern start). The MCU timestamps each edge with its own
// microsecond counter: tau_k = offset + rate * t_k + jitter. FitTimeBase indexes the edges
// (robust to missing and spurious edges), fits offset and rate by least squares with outlier
// rejection, and reports the residual jitter.

#include <cstdint>
#include <string>
#include <vector>

namespace msmcal::hall {

struct TimeBase {
  double offset_us = 0;         // MCU time of generator time 0 (the first kept edge's pattern)
  double rate_us_per_s = 1e6;   // MCU microseconds per generator second (1e6 * (1 + error))
  double pattern_period_s = 0;  // T
  // Figures of the fit.
  int edges_used = 0;
  int edges_rejected = 0;    // spurious or off-grid edges
  int edges_missing = 0;     // gaps in the edge index sequence
  double jitter_rms_us = 0;  // residual RMS of the kept edges

  double GeneratorTime(double mcu_time_us) const {
    return (mcu_time_us - offset_us) / rate_us_per_s;
  }
  double McuTime(double generator_time_s) const {
    return offset_us + rate_us_per_s * generator_time_s;
  }
  // Rate error in parts per million.
  double RateErrorPpm() const { return (rate_us_per_s / 1e6 - 1.0) * 1e6; }
};

struct TimeBaseOptions {
  // Maximum |rate error| accepted, ppm (crystal oscillators: tens of ppm).
  double max_rate_error_ppm = 2000;
  // An edge whose fractional index differs from an integer by more than this fraction of a
  // period is rejected as spurious.
  double max_phase_error = 0.05;
  std::string Validate() const;
};

// Throws std::invalid_argument with a clear message when fewer than 2 usable edges exist or
// the edges do not fit a clock of period T.
TimeBase FitTimeBase(const std::vector<double>& clock_edges_us, double pattern_period_s,
                     const TimeBaseOptions& options = {});

}  // namespace msmcal::hall

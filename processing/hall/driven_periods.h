#pragma once
// Which pattern periods of a Hall recording were taken while both drives ran (the mirror
// scanning), from the readings themselves.
//
// Why: a lab session plays each step 2 frame's own signals (docs/lab-path.md, "Per-frame
// signals"): neutral frames with both drive outputs off, fast-only frames with the slow drive
// off. The actual Hall recording runs through all of step 2, so it holds neutral and fast-only
// stretches as well as the scan. Folded over the pattern period they were averaged into the
// scan's profile: the mirror poses then belong to a profile that no drive state produced.
//
// How: for every whole pattern period k (generator time [kT, (k+1)T)) of the readings, the
// amplitude of the field at the slow and at the fast drive frequency (the norm over the three
// axes of the complex projection; a whole period holds a whole number of cycles of both, so
// constants drop out). A drive that is off leaves only noise at its frequency (the coils'
// field and the magnet's motion both vanish). A period is driven when both amplitudes reach
// min_amplitude_ratio of their reference, the 90th percentile over the recording's periods
// (a recording that is all scan keeps every whole period); periods within margin_periods of a
// period that is not driven are left out too (a drive switched during it, the resonator
// settling). A partial period (the recording's ends, a gap) is used when the whole periods
// next to it are.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace msmcal::hall {

struct DrivenPeriodOptions {
  bool enabled = true;               // false: every reading is used (the recording is all scan)
  double min_amplitude_ratio = 0.8;  // of the reference amplitude, per drive frequency
  int margin_periods = 1;            // left out on each side of a period that is not driven
  // A whole period needs this fraction of the readings a full period holds at the median
  // sample spacing.
  double min_coverage = 0.9;
  std::string Validate() const;
};

struct DrivenPeriods {
  std::vector<bool> use;  // per reading: inside a driven period
  int periods = 0;        // whole pattern periods in the recording
  int driven = 0;         // of them used
  int not_driven = 0;     // below the amplitude threshold (drive off or fast only)
  int margin = 0;         // driven, but next to a period that is not
  size_t readings_used = 0;
};

// t_s: generator times (ascending; MapReadings), b: raw fields (uT). Frequencies in Hz (a
// frequency <= 0 is not tested). Throws std::invalid_argument for bad options or input.
DrivenPeriods SelectDrivenPeriods(const std::vector<double>& t_s,
                                  const std::vector<Eigen::Vector3d>& b, double pattern_period_s,
                                  double fast_frequency_hz, double slow_frequency_hz,
                                  const DrivenPeriodOptions& options = {});

}  // namespace msmcal::hall

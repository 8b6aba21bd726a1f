#pragma once
// Progress of a sweep: the orchestrator's typed session events applied to one progress line, the
// ETA estimate and the line's format (issue 9: "a progress line (step, ETA, frames, dropped
// readings)"). Pure: times are passed in (seconds of an injected monotonic clock).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "sessions/orchestrator/session_events.h"

namespace msmcal::sweep {

// "42 s", "3:05", "1:02:03"; "?" when negative or not finite.
std::string FormatDuration(double seconds);

// ETA from the durations of points run from start to end (resumed or skipped points are not
// representative and are not added).
class EtaEstimator {
 public:
  void AddPointDuration(double seconds);
  size_t samples() const { return samples_; }
  // Seconds left for `points_after_current` points plus the current one, which has run for
  // `current_elapsed_s` (infinity: the current point is over); nullopt before the first sample.
  std::optional<double> EtaSeconds(size_t points_after_current, double current_elapsed_s) const;

 private:
  double sum_s_ = 0;
  size_t samples_ = 0;
};

// The state of the sweep shown in one progress line.
struct ProgressSnapshot {
  size_t point = 0, points = 0;  // 1-based point number, total
  std::string label;             // the point's values ("fast.frequency_hz=205 r0")
  std::string step;              // "step 1 frame 3/15", "Hall background", "solve", ...
  std::string event;             // what just happened ("accepted", "REJECTED", "done", ...)
  size_t frames_accepted = 0, frames_rejected = 0;  // this point so far
  uint64_t lost = 0;                                // Hall readings lost at this point so far
  double elapsed_s = 0;                             // since the sweep run started
  std::optional<double> eta_s;                      // whole sweep
};
// "sweep 2/4 [fast.frequency_hz=205 r0] step 1 frame 3/15 accepted | frames 3 ok 0 rejected |
// lost 0 | elapsed 1:23 | ETA 2:10" (one line, no newline).
std::string FormatProgressLine(const ProgressSnapshot& s);

// Updates `s` (step, event, frame and loss counts) from one session event; returns false when the
// event does not change the progress line.
bool ApplyEvent(const orchestrator::SessionEvent& e, ProgressSnapshot* s);

}  // namespace msmcal::sweep

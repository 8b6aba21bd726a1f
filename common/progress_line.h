#pragma once
// A progress line with ETA for long commands (`msmcal solve`, `simulate`, `hall calibrate`,
// `experiment ...`; issue 19): redrawn in place ("\r", clear to the end of the line) when its
// stream is a terminal, silent when it is not (a pipe or a file gets no progress, so scripts and
// logs see only the commands' own output).
//
//   solve: 12/43 images (28%), 0:05 elapsed, ETA 0:13
//
// The ETA is the mean time per unit so far times the units left ("ETA -" before the first).
// Thread safety: Update() may be called from several threads (image workers).

#include <cstdio>
#include <functional>
#include <mutex>
#include <string>

namespace msmcal::common {

// The line's text (pure): label, done/total and unit, percentage, elapsed, ETA, detail.
std::string FormatProgressLine(const std::string& label, size_t done, size_t total,
                               const std::string& unit, double elapsed_s,
                               const std::string& detail);

class ProgressLine {
 public:
  // Draws on `stream` only when isatty(fileno(stream)). `unit`: what is counted ("images").
  ProgressLine(std::string label, size_t total, std::string unit, std::FILE* stream = stderr);
  // For tests: `enabled` instead of the terminal check, and the clock (seconds).
  ProgressLine(std::string label, size_t total, std::string unit, std::FILE* stream, bool enabled,
               std::function<double()> clock_s);
  ~ProgressLine();  // Finish()
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  // `done` units finished (clamped to total). Redraws at most every 0.2 s, and always for the
  // last unit. `detail` (optional) follows the figures ("row 3: Pattern-A-3").
  void Update(size_t done, const std::string& detail = "");
  // Adds one to the units done (thread-safe counter) and redraws as Update does.
  void Step(const std::string& detail = "");
  // Ends the line with a newline (only when something was drawn); later calls draw nothing.
  void Finish();
  bool enabled() const { return enabled_; }

 private:
  void DrawLocked(bool force);

  const std::string label_, unit_;
  const size_t total_;
  std::FILE* const stream_;
  const bool enabled_;
  const std::function<double()> clock_s_;
  const double start_s_;
  std::mutex mu_;
  size_t done_ = 0;
  std::string detail_;
  double last_draw_s_ = -1e300;
  bool drawn_ = false, finished_ = false;
};

}  // namespace msmcal::common

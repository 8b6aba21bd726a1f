#pragma once
// The sweep runner (issue 9, sweep mode): runs one calibration session per plan point into
// DIR/<point name>, unattended — a failing point is recorded with its reason and the sweep goes
// on — and resumable: re-running on the same DIR continues (DecidePointAction per point).
// The acquisition and the steps after it are injected (`msmcal sweep` passes the demo rig's
// RunDemoAcquisition and FinishSession; tests pass fakes), and so is the clock.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "sessions/orchestrator/session_events.h"
#include "sessions/sweep/sweep_plan.h"
#include "sessions/sweep/sweep_progress.h"
#include "sessions/sweep/sweep_state.h"
#include "sessions/sweep/sweep_summary.h"

namespace msmcal::sweep {

struct SweepHooks {
  // What is on disk for a point's folder (journal state, results).
  std::function<PointFolderState(const std::filesystem::path& folder)> inspect;
  // Runs (resume = false) or continues (resume = true) the point's acquisition into `folder`;
  // every typed session event goes to `on_event` (OrchestratorOptions::on_event). Throws on
  // failure (the message is the point's failure reason).
  std::function<void(const SweepPoint& point, const std::filesystem::path& folder, bool resume,
                     const orchestrator::SessionEventObserver& on_event)>
      acquire;
  // The steps after a complete acquisition (solve, Hall calibration), skipping those whose
  // outputs exist. Returns "" on success, else the reason.
  std::function<std::string(const SweepPoint& point, const std::filesystem::path& folder)> finish;
  // Optional: adds figures to a point's summary row (e.g. the comparison with the simulator's
  // truth from the session report). Must not throw.
  std::function<void(const std::filesystem::path& folder, PointFigures* figures)> augment;
  // Monotonic seconds (injected clock).
  std::function<double()> now_s;
  // Receives every progress line; `transient` lines may be overwritten by the next one (TTY
  // redraw), the others are events worth keeping (point start/end, summary).
  std::function<void(const std::string& line, bool transient)> print;
};

struct SweepOutcome {
  std::vector<SummaryRow> rows;
  size_t done = 0, failed = 0;
  std::string table;  // SummaryTable
};

// Runs `plan` into `dir`. `dir` is created if absent; when it holds a sweep (DIR/sweep.yaml) the
// plans must expand to the same points, else std::runtime_error ("holds a different sweep: …").
// A non-empty folder that is not a sweep is refused. Writes DIR/sweep.yaml, DIR/sweep_state.json
// (after every point) and DIR/summary.csv (at the end).
SweepOutcome RunSweep(const SweepPlan& plan, const std::filesystem::path& dir,
                      const SweepHooks& hooks);

// The folder name a set-aside point folder gets: "<name>.set-aside-<n>" with the first free n.
std::filesystem::path SetAsideName(const std::filesystem::path& folder);

}  // namespace msmcal::sweep

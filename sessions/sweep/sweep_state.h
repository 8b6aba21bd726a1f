#pragma once
// Sweep state and the resume decision (issue 9, sweep mode).
//
// What a sweep folder holds: DIR/sweep.yaml (the plan, self-contained), DIR/sweep_state.json
// (one record per point: status, reason, duration, attempts; rewritten atomically after every
// point), DIR/summary.csv (the table at the end) and one session folder per point
// (DIR/<point name>, see PointFolderName). The per-point decision depends only on what is on
// disk in the point's folder, so that a sweep killed at any moment (SIGKILL included) continues
// where it stopped: a point never loses what its session journal recorded.

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>

namespace msmcal::sweep {

// What is on disk for one point (filled by the runner's inspector from the folder and its
// session journal; see ReadSessionJournal in sessions/orchestrator).
struct PointFolderState {
  bool folder_exists = false;
  bool folder_empty = true;       // absent or without any entry
  bool journal_exists = false;    // a session.db is there
  bool session_complete = false;  // the journal says session.yaml was written
  bool results_complete = false;  // solve + Hall calibration + prediction outputs all present
};

enum class PointAction {
  kAcquire,   // nothing recorded: start the session (folder absent or empty)
  kResume,    // a journal with an unfinished acquisition: continue it (resume = true)
  kFinish,    // acquisition complete, results missing: run the steps after acquisition only
  kSkip,      // results complete: nothing to do
  kSetAside,  // files without a journal (killed before the journal existed): move the folder
              // aside (kept, renamed) and start again
};
const char* ToString(PointAction action);
// The decision for one point. Pure.
PointAction DecidePointAction(const PointFolderState& state);

enum class PointStatus { kPending, kRunning, kDone, kFailed };
const char* ToString(PointStatus status);

struct PointRecord {
  PointStatus status = PointStatus::kPending;
  std::string reason;             // why it failed (kFailed)
  double duration_s = 0;          // wall time of its runs, summed over attempts (s)
  int attempts = 0;               // runs started (a resumed point has 2 or more)
  bool skipped_last_run = false;  // the last sweep run found its results complete
};

// DIR/sweep_state.json: point name -> record.
struct SweepState {
  std::map<std::string, PointRecord> points;
};
// Reads the state file; an absent file gives an empty state. Throws std::runtime_error naming
// the file and the field for a malformed file.
SweepState ReadSweepState(const std::filesystem::path& file);
// Writes atomically (temporary file, fsync, rename).
void WriteSweepState(const std::filesystem::path& file, const SweepState& state);

}  // namespace msmcal::sweep

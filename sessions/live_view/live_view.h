#pragma once
// The live view of a guided session (issue 19): the state a web page shows and the commands it
// sends, independent of HTTP (sessions/live_view/live_server.h serves it; WebOperator asks
// through it).
//
// A LiveView collects, as typed events from the orchestrator (never from log lines):
//   - the camera image: every frame the preview pump streams while the operator is asked
//     (orchestrator::LiveFrame), run through the quality gate for the frame being set up
//     (optionally on a downscaled copy) and drawn with what the gate sees (boards' corners,
//     outline, origin and axes; dots with their labels; the region where dots are expected),
//     downscaled and JPEG-encoded; and the frame of every gate decision, drawn the same way;
//   - the live figures of every gate decision (accepted / rejected and why, the totals);
//   - the rig's state (outputs on, reference locked, Hall readings per second and lost) and the
//     disk space left in the session folder;
//   - the current set-up instruction and its position ("[k/N]"), the frame counters, progress
//     and an ETA;
// and hands the commands of the controlling page (Ready, Repeat, Abort) to the operator.
//
// One controlling page at a time: a page claims control and gets a random controller token;
// while that token is seen (its event stream open, or a request made) within the lease, every
// other claim is refused: those pages watch. Reloading a page keeps its token (the page stores
// it), so a reload keeps control and aborts nothing; closing it lets the lease run out.
//
// Thread safety: every member function may be called from any thread.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/orchestrator/quality_gate.h"

namespace msmcal::live_view {

// What the page's `state` element says.
enum class SessionState {
  kRunning,  // the session works (frames, recordings); nothing to confirm
  kWaiting,  // an instruction waits for Ready / Repeat / Abort
  kDone,     // the acquisition ended and the session is written
  kAborted,  // the session ended early (abort or failure) in the safe state
};
const char* ToString(SessionState state);  // "running" | "waiting" | "done" | "aborted"

enum class Command { kReady, kRepeat, kAbort };
const char* ToString(Command command);  // "ready" | "repeat" | "abort"

struct LiveViewOptions {
  int image_max_width_px = 960;  // the page's image (aspect kept)
  int jpeg_quality = 80;         // 1..100
  // Live frames wider than this are downscaled before the gate looks at them (<= 0: never).
  int detect_max_width_px = 1600;
  double max_live_fps = 4.0;  // live frames processed per second at most (> 0); others skipped
  // A controller not seen for this long loses control (another page may claim it).
  std::chrono::milliseconds controller_lease{5000};
  orchestrator::GateOptions gate;
  std::filesystem::path disk_path;  // the session folder (disk left); empty: not shown
  size_t log_lines = 12;            // recent progress lines kept for the page
  // Empty when valid; otherwise names the field, its value and the constraint.
  std::string Validate() const;
};

// The outcome of a page's request, with the HTTP status the server answers with.
struct Reply {
  int http_status = 200;         // 200 ok, 403 not the controller, 409 nothing to do / refused
  std::string error;             // empty when ok
  std::string controller_token;  // Claim: the token to send with every command
};

// What an operator asks the page (one instruction block).
struct Prompt {
  std::string title;          // the block's header line ("Step 1, frame 3 of 7 (step1/0002.png)")
  std::string instructions;   // the whole block, as the console prints it
  int number = 0, total = 0;  // "[number/total]"
  // The frame being set up: step 1 or 2 and its index into the plan's list; step 0: a Hall
  // recording's set-up.
  int step = 0;
  size_t index = 0;
  // The set-up as a hook program gets it (setup::SetupToJson, docs/lab-path.md), for scripts
  // driving the page (the state's prompt.setup); empty: none.
  std::string setup_json;
};

class LiveView {
 public:
  // `plan` must outlive the view. Throws std::invalid_argument when options.Validate() fails.
  LiveView(const dataset::Recording& plan, LiveViewOptions options);
  ~LiveView();
  LiveView(const LiveView&) = delete;
  LiveView& operator=(const LiveView&) = delete;

  // --- Feeds (the orchestrator's observers; chain them into OrchestratorOptions). ---
  orchestrator::FrameObserver MakeFrameObserver();
  orchestrator::LiveFrameObserver MakeLiveFrameObserver();
  orchestrator::RigStatusObserver MakeRigStatusObserver();
  void AddLogLine(const std::string& line);  // a progress line (the last few are shown)
  void SetState(SessionState state, const std::string& message = "");

  // --- The operator's side. ---
  // Shows `prompt`, sets the state to waiting and blocks until the controlling page answers
  // Ready (returns kReady; state running again) or Abort (returns kAbort); Repeat shows the
  // block again and keeps waiting. Returns kAbort at once when an abort is pending (requested
  // while no prompt was shown) or the view was closed.
  Command Ask(const Prompt& prompt);
  // True once Abort was requested (a prompt's, or one sent while the session was running).
  bool AbortRequested() const;
  // Ends every Ask (kAbort) and every event stream's wait; the view still answers requests.
  void Close();

  // --- The page's side (live_server.cc). ---
  // `previous` (may be empty): the token this page held before (a reload).
  Reply Claim(const std::string& previous);
  // Ready / Repeat need the number of the prompt they answer (the page's `prompt` field), so a
  // late or doubled click never confirms the next instruction; Abort is taken at any time.
  Reply Submit(const std::string& controller_token, Command command, int64_t prompt_id);
  void SeeController(const std::string& controller_token);  // keeps its lease
  // The page's state as JSON (schema in docs/guided.md, "Live view").
  std::string StateJson() const;
  // The latest image (JPEG bytes; null before the first) and its sequence number.
  std::shared_ptr<const std::string> Image(uint64_t* sequence) const;
  // Blocks until the state changed after `version` (returns the new version), the timeout
  // passed or the view was closed (returns `version`). version() is the current one.
  uint64_t WaitForChange(uint64_t version, std::chrono::milliseconds timeout) const;
  uint64_t version() const;
  bool closed() const;
  // How often an event stream writes at the latest (a keepalive when nothing changed): well
  // inside the controller's lease, at most a second.
  std::chrono::milliseconds keepalive_interval() const;

 private:
  struct Figures;
  void Changed();  // with mu_ held: bumps the version and wakes the waiters
  void PublishImage(std::string jpeg);
  bool ControllerActive(std::chrono::steady_clock::time_point now) const;  // mu_ held
  void ProcessLiveFrame(const orchestrator::LiveFrame& frame);
  void ProcessDecision(const orchestrator::FrameReport& report);

  const dataset::Recording& plan_;
  const LiveViewOptions options_;
  const std::chrono::steady_clock::time_point started_;

  mutable std::mutex mu_;
  mutable std::condition_variable cv_;
  uint64_t version_ = 1;
  bool closed_ = false;
  SessionState state_ = SessionState::kRunning;
  std::string state_message_;
  // The prompt shown (id 0: none yet) and the answer given to it.
  Prompt prompt_;
  int64_t prompt_id_ = 0;
  bool waiting_ = false;
  std::optional<Command> answer_;
  int repeats_ = 0;  // Repeat answers to the prompt shown
  bool abort_requested_ = false;
  // Controller.
  std::string controller_token_;
  std::chrono::steady_clock::time_point controller_seen_{};
  // Image.
  std::shared_ptr<const std::string> image_;
  uint64_t image_sequence_ = 0;
  std::string image_caption_;
  std::chrono::steady_clock::time_point last_live_{};
  // Figures and progress.
  std::unique_ptr<Figures> figures_;
  std::vector<std::string> log_;
  orchestrator::RigStatus rig_;
  double hall_rate_per_s_ = 0;
  std::chrono::steady_clock::time_point rig_seen_{};
  mutable std::chrono::steady_clock::time_point disk_checked_{};
  mutable double disk_free_bytes_ = -1;
};

// The ids the page's elements carry (scripts and the tests drive the page by them).
inline constexpr const char* kPageIds[] = {"instruction", "live-image", "ready",
                                           "repeat",      "abort",      "state"};

}  // namespace msmcal::live_view

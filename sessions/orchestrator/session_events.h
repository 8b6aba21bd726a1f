#pragma once
// Typed events of a running session (issue 16: "typed events delivered to observers"). The
// orchestrator emits one SessionEvent per fact it also writes as a log line; observers (the
// sweep's progress line, a live view, tests) read the fields, never the text. `text` is the log
// line rendered from the same fact, for observers that only print.
//
// Delivered on the orchestrator's thread, except kSafeState, which the safe-state watcher may
// deliver from its own thread on a signal: observers must be thread-safe for that one.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

namespace msmcal::orchestrator {

struct SessionEvent {
  enum class Kind {
    kFrameDecided,    // a plan frame's final gate decision (or one kept from before a resume)
    kHallStarted,     // a Hall recording started
    kHallDone,        // a Hall recording completed and journalled
    kStepState,       // a named step (kStep1, ...) changed state
    kSafeState,       // the generator outputs were switched off
    kSessionWritten,  // session.yaml written: the folder is complete
  };
  Kind kind = Kind::kFrameDecided;
  // kFrameDecided
  int step = 0;                 // 1 or 2
  size_t index = 0, count = 0;  // 0-based index into the plan's step list, frames in that step
  std::string file;             // as in session.yaml ("step1/0002.png")
  bool accepted = false;
  bool from_journal = false;  // recorded before a resume and kept
  std::string reason;         // rejected: why
  // kHallStarted / kHallDone
  std::string recording;                                    // "background" | "actual"
  std::string device;                                       // kHallStarted: the MCU's serial device
  uint64_t readings = 0, edges = 0, lost = 0, dropped = 0;  // kHallDone
  // kStepState
  std::string step_name, state;  // (kStep1, "running"), ...
  // kSafeState
  bool confirmed = false;  // every output queried back as off
  bool on_signal = false;  // switched off by the signal watcher
  // kSessionWritten
  size_t step1_accepted = 0, step2_accepted = 0;
  std::string text;  // the log line of this fact
};

using SessionEventObserver = std::function<void(const SessionEvent&)>;

}  // namespace msmcal::orchestrator

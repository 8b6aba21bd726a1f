#pragma once
// The guided mode (issue 9): a RigOperator that tells the person at the rig what to do next, on
// a terminal, and waits for the answer before the orchestrator goes on.
//
// The orchestrator asks for every frame and Hall recording (RigOperator::Prepare*); the console
// prompts only when the physical set-up changes: the plan's frames are grouped into set-ups
// (sessions/setup: consecutive frames of a step with equal camera position, MSM / top frame,
// sliding plate pose, unblocked beams and drive mode), and a frame whose set-up is the one
// confirmed last runs without a prompt (repeated exposures, frames differing only in their
// triggers). Each set-up prints its instruction block (rendered from the Setup: position in the
// session, what to mount or remove, the drive mode, the frames it covers, which beams to
// unblock) followed by the prompt
//   [Enter] ready  [r] repeat instructions  [q] abort
// and reads one line from its input. Enter (an empty line) confirms; "r" prints the block again;
// "q" — and the end of the input — throws OperatorAbort, which RunSession treats like any other
// failure (generator outputs off, the abort recorded in the session log / journal).
//
// An optional inner RigOperator actually changes the rig (the demo's SimulatedWorld); it is told
// about every frame (the frame's trigger selection is not physical), after the confirmation when
// there was a prompt. Without one (the lab) the human does it, and ConsoleOperator itself decides
// which frames show the set-up (FrameShowsCurrentSetup): see ConsoleOperatorOptions.
//
// The orchestrator's call order is: step-1 frames, PrepareHallRecording(background) (the mirror's
// top frame removed; the recording starts right after the confirmation), then
// PrepareHallRecording(actual) (top frame mounted) and the step-2 frames. When
// OrchestratorOptions::mcu.device is empty the background call comes first instead (before the
// rig check: the MCU's device is needed for it) and the background recording follows step 1
// without another prompt; the instruction texts say which. The first call tells the order, and
// the blocks are numbered "[k/N]" in it (N = the plan's set-ups). A resumed session skips the
// blocks of frames already recorded, keeping the numbers; its first frame always prompts.
//
// Thread safety: Prepare* and FrameShowsCurrentSetup are called from the orchestrator's thread.

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/orchestrator/rig_operator.h"
#include "sessions/orchestrator/setup_operator.h"
#include "sessions/setup/setup.h"

namespace msmcal::orchestrator {

// The operator answered 'q' at a prompt, or the input ended (EOF, closed terminal).
class OperatorAbort : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ConsoleOperatorOptions {
  int input_fd = 0;   // lines typed by the operator (not owned, not closed)
  int output_fd = 1;  // instructions and prompts (not owned, not closed)
  // Optional, per step-1 pose index l: where the sliding plate goes, in the mount instruction
  // ("about 35 mm from the mirror position towards the source, tilted +12 deg") and the Setup.
  std::vector<setup::PoseGeometry> poses;

  // Lab only (no inner operator):
  // The Hall MCU's serial device for both recordings (returned by PrepareHallRecording).
  std::string mcu_device;
  // The clock the camera driver stamps FrameInfo::host_timestamp_ns with, in ns (Aravis:
  // CLOCK_REALTIME, see arv_buffer_get_system_timestamp; V4L2: CLOCK_MONOTONIC). Read when the
  // operator confirms a setup.
  std::function<int64_t()> host_clock_ns;
  // A frame shows the confirmed setup when it reached the host at least this long after the
  // confirmation (or, for a frame of an unchanged set-up, after its Prepare*Frame call): the host
  // arrival time bounds the end of the exposure, so this must cover one exposure + transfer
  // (frames in flight at the confirmation are discarded).
  int64_t settle_ns = 300'000'000;
  // The longest exposure a frame can have (ns). Set: a frame also counts only when its exposure
  // began after the confirmation on the camera's own clock (its device timestamp, mapped onto the
  // host clock by the fastest-delivered frame: camera::DeviceClockMap), which a frame delivered
  // late by a loaded host fails however late it arrives. 0: the host rule alone.
  int64_t exposure_ns = 0;

  // Empty when valid for the given mode (with or without an inner operator); otherwise names the
  // field, its value and the constraint.
  std::string Validate(bool has_inner) const;
};

inline constexpr const char* kConsolePrompt =
    "[Enter] ready  [r] repeat instructions  [q] abort > ";

class ConsoleOperator : public SetupOperator {
 public:
  // `plan` and `inner` (may be null: lab) must outlive the operator. Throws std::invalid_argument
  // when options.Validate(inner != nullptr) fails.
  ConsoleOperator(const dataset::Recording& plan, ConsoleOperatorOptions options,
                  RigOperator* inner);

 private:
  // Prints the set-up's block and the prompt until the operator confirms; throws OperatorAbort.
  void Present(const setup::Setup& s) override;
  void Write(const std::string& text) const;
  // One line from the input without the newline; false at EOF.
  bool ReadLine(std::string* line);

  ConsoleOperatorOptions options_;
  std::string pending_;  // bytes read past the last line
};

// Live quality figures: an observer that prints one line per gate decision (file, attempt,
// boards found or not, dots found/expected, saturated %, accepted or the rejection reason, and
// the running totals of final decisions). Not thread-safe (RunSession calls it from one thread).
struct LiveTotals {
  int accepted = 0;
  int rejected = 0;  // final rejections
  int retried = 0;   // non-final rejections (another attempt follows)
};
std::string FormatLiveFigures(const FrameReport& report, const LiveTotals& totals_after);
FrameObserver MakeLiveFigures(std::function<void(const std::string& line)> print);

}  // namespace msmcal::orchestrator

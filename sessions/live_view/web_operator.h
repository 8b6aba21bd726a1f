#pragma once
// The guided mode's operator on a web page (issue 19): a RigOperator that shows each set-up
// instruction on the live view's page (the same blocks ConsoleOperator prints, rendered from the
// session's set-ups: setup::PlanSetups, one prompt per physical set-up) and waits for the
// controlling page's answer, with the console's meaning: Ready confirms (then, in the demo, the
// inner operator changes the simulated world), Repeat shows the block again, Abort throws
// orchestrator::OperatorAbort, which RunSession treats like the console's `q` (camera stopped,
// every generator output off and confirmed, the abort in session_log.txt and the journal, no
// session.yaml).
//
// An Abort sent while the session is running (no instruction shown) is taken at the next
// operator call: the next FrameShowsCurrentSetup (within one camera frame while a frame is
// taken) or the next Prepare*; during a Hall recording without frames it waits for the
// recording's end.
//
// Call order, numbering ("[k/N]") and the lab freshness rule are those of ConsoleOperator
// (sessions/orchestrator/console_operator.h). Thread safety: called from the orchestrator's
// thread; the LiveView is thread-safe.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "sessions/live_view/live_view.h"
#include "sessions/orchestrator/rig_operator.h"
#include "sessions/orchestrator/setup_operator.h"
#include "sessions/setup/setup.h"

namespace msmcal::live_view {

struct WebOperatorOptions {
  // Per step-1 pose index: where the sliding plate goes (ConsoleOperatorOptions::poses).
  std::vector<setup::PoseGeometry> poses;
  // Also gets every instruction block and the outcome of each answer (the terminal; may be
  // empty).
  std::function<void(const std::string& text)> echo;
  // Lab only (no inner operator), as ConsoleOperatorOptions: the MCU device for both recordings,
  // the camera driver's host clock and the settle time after a confirmation.
  std::string mcu_device;
  std::function<int64_t()> host_clock_ns;
  int64_t settle_ns = 300'000'000;
  int64_t exposure_ns = 0;  // as SetupWalkOptions::exposure_ns (0: host rule alone)
  std::string Validate(bool has_inner) const;  // empty when valid; names field and constraint
};

class WebOperator : public orchestrator::SetupOperator {
 public:
  // `plan`, `view` and `inner` (may be null: lab) must outlive the operator. Throws
  // std::invalid_argument when options.Validate(inner != nullptr) fails.
  WebOperator(const dataset::Recording& plan, LiveView& view, WebOperatorOptions options,
              orchestrator::RigOperator* inner);

  // Throws OperatorAbort when the page asked for an abort meanwhile.
  bool FrameShowsCurrentSetup(const camera::FrameInfo& info) const override;

 private:
  // Shows the set-up's block until Ready; throws OperatorAbort on Abort.
  void Present(const setup::Setup& s) override;
  void Echo(const std::string& text) const;

  LiveView& view_;
  WebOperatorOptions options_;
};

// The exception messages (what session_log.txt records).
inline constexpr const char* kWebAbortMessage =
    "guided mode: operator aborted the session from the web page";

}  // namespace msmcal::live_view

#include "sessions/live_view/web_operator.h"

#include <stdexcept>
#include <utility>

#include "sessions/orchestrator/console_operator.h"
#include "sessions/setup/setup.h"

namespace msmcal::live_view {
namespace {

// "\n=== [3/22] Step 1, frame 3 of 7 (step1/0002.png) ===\n..." -> the title between the marks.
std::string TitleOf(const std::string& block) {
  const size_t a = block.find("] ");
  const size_t b = block.find(" ===", a == std::string::npos ? 0 : a);
  if (a == std::string::npos || b == std::string::npos) return {};
  return block.substr(a + 2, b - a - 2);
}

}  // namespace

std::string WebOperatorOptions::Validate(bool has_inner) const {
  if (settle_ns < 0)
    return "WebOperatorOptions.settle_ns = " + std::to_string(settle_ns) + ": must be >= 0";
  if (!has_inner) {
    if (mcu_device.empty())
      return "WebOperatorOptions.mcu_device = '': required without an inner operator (lab)";
    if (!host_clock_ns)
      return "WebOperatorOptions.host_clock_ns = (none): required without an inner operator (lab)";
  }
  return {};
}

namespace {

orchestrator::SetupWalkOptions WalkOf(const WebOperatorOptions& o, bool has_inner) {
  if (std::string e = o.Validate(has_inner); !e.empty()) throw std::invalid_argument(e);
  return {o.poses, o.mcu_device, o.host_clock_ns, o.settle_ns, o.exposure_ns};
}

}  // namespace

WebOperator::WebOperator(const dataset::Recording& plan, LiveView& view, WebOperatorOptions options,
                         orchestrator::RigOperator* inner)
    : SetupOperator(plan, WalkOf(options, inner != nullptr), inner),
      view_(view),
      options_(std::move(options)) {}

void WebOperator::Echo(const std::string& text) const {
  if (options_.echo) options_.echo(text);
}

void WebOperator::Present(const setup::Setup& s) {
  Prompt p;
  p.instructions = s.text;
  // The block without its leading newline; the title is its header line's text.
  if (!p.instructions.empty() && p.instructions.front() == '\n') p.instructions.erase(0, 1);
  p.title = TitleOf(s.text);
  p.number = s.block;
  p.total = s.of;
  p.step = s.step == setup::SetupStep::kStep1 ? 1 : s.step == setup::SetupStep::kStep2 ? 2 : 0;
  p.index = s.frame_indices.empty() ? 0 : s.frame_indices.front();
  p.setup_json = setup::SetupToJson(s);
  Echo(s.text + "[waiting for the web page: Ready / Repeat / Abort]\n");
  if (view_.Ask(p) != Command::kReady) {
    Echo("aborted from the web page.\n");
    throw orchestrator::OperatorAbort(kWebAbortMessage);
  }
  Echo("ok (web page).\n");
}

bool WebOperator::FrameShowsCurrentSetup(const camera::FrameInfo& info) const {
  if (view_.AbortRequested()) throw orchestrator::OperatorAbort(kWebAbortMessage);
  return SetupOperator::FrameShowsCurrentSetup(info);
}

}  // namespace msmcal::live_view

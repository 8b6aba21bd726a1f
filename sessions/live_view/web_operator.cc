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

WebOperator::WebOperator(const dataset::Recording& plan, LiveView& view, WebOperatorOptions options,
                         orchestrator::RigOperator* inner)
    : plan_(plan), view_(view), options_(std::move(options)), inner_(inner) {
  if (std::string e = options_.Validate(inner_ != nullptr); !e.empty())
    throw std::invalid_argument(e);
  setups_ = setup::PlanSetups(plan_, options_.poses, /*background_first=*/false);
  total_ = static_cast<int>(setups_.setups.size());
}

void WebOperator::Echo(const std::string& text) const {
  if (options_.echo) options_.echo(text);
}

void WebOperator::Ask(const std::string& instructions, int number, int step, size_t index) {
  Prompt p;
  p.instructions = instructions;
  // The block without its leading newline; the title is its header line's text.
  if (!p.instructions.empty() && p.instructions.front() == '\n') p.instructions.erase(0, 1);
  p.title = TitleOf(instructions);
  p.number = number;
  p.total = total_;
  p.step = step;
  p.index = index;
  Echo(instructions + "[waiting for the web page: Ready / Repeat / Abort]\n");
  const Command c = view_.Ask(p);
  if (c != Command::kReady) {
    Echo("aborted from the web page.\n");
    throw orchestrator::OperatorAbort(kWebAbortMessage);
  }
  ++confirmations_;
  Echo("ok (web page).\n");
}

void WebOperator::SeeFirstCall(bool is_background) {
  if (order_known_) return;
  order_known_ = true;
  background_first_ = is_background;
  if (background_first_) setups_ = setup::PlanSetups(plan_, options_.poses, true);
}

void WebOperator::Enter(int k) {
  if (k == current_) return;
  const setup::Setup& s = setups_.setups.at(static_cast<size_t>(k));
  const int step = s.step == setup::SetupStep::kStep1   ? 1
                   : s.step == setup::SetupStep::kStep2 ? 2
                                                        : 0;
  Ask(s.text, s.block, step, s.frame_indices.empty() ? 0 : s.frame_indices.front());
  current_ = k;
}

void WebOperator::PrepareStep1Frame(size_t index) {
  SeeFirstCall(false);
  Enter(setups_.step1_setup.at(index));
  if (inner_)
    inner_->PrepareStep1Frame(index);
  else
    confirmed_ns_ = options_.host_clock_ns();
}

void WebOperator::PrepareStep2Frame(size_t index) {
  SeeFirstCall(false);
  Enter(setups_.step2_setup.at(index));
  if (inner_)
    inner_->PrepareStep2Frame(index);
  else
    confirmed_ns_ = options_.host_clock_ns();
}

bool WebOperator::FrameShowsCurrentSetup(const camera::FrameInfo& info) const {
  if (view_.AbortRequested()) throw orchestrator::OperatorAbort(kWebAbortMessage);
  if (inner_) return inner_->FrameShowsCurrentSetup(info);
  return info.host_timestamp_ns - confirmed_ns_ >= options_.settle_ns;
}

std::string WebOperator::PrepareHallRecording(orchestrator::HallRun run) {
  SeeFirstCall(run == orchestrator::HallRun::kBackground);
  current_ = -1;  // a Hall set-up is always asked for (its recording starts on the answer)
  Enter(run == orchestrator::HallRun::kBackground ? setups_.background_setup
                                                  : setups_.actual_setup);
  if (inner_) return inner_->PrepareHallRecording(run);
  confirmed_ns_ = options_.host_clock_ns();
  return options_.mcu_device;
}

}  // namespace msmcal::live_view

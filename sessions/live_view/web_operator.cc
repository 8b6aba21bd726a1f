#include "sessions/live_view/web_operator.h"

#include <stdexcept>
#include <utility>

#include "sessions/orchestrator/console_operator.h"

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
  total_ = static_cast<int>(2 + plan_.step1.size() + plan_.step2.size());
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
}

void WebOperator::PrepareStep1Frame(size_t index) {
  SeeFirstCall(false);
  const int number = static_cast<int>(index) + (background_first_ ? 2 : 1);
  Ask(orchestrator::DescribeStep1Frame(plan_, index, options_.pose_hints, number, total_), number,
      1, index);
  if (inner_)
    inner_->PrepareStep1Frame(index);
  else
    confirmed_ns_ = options_.host_clock_ns();
}

void WebOperator::PrepareStep2Frame(size_t index) {
  SeeFirstCall(false);
  const int number = static_cast<int>(3 + plan_.step1.size() + index);
  Ask(orchestrator::DescribeStep2Frame(plan_, index, number, total_), number, 2, index);
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
  const int n1 = static_cast<int>(plan_.step1.size());
  const int number =
      run == orchestrator::HallRun::kActual ? 2 + n1 : (background_first_ ? 1 : 1 + n1);
  Ask(orchestrator::DescribeHallRecording(plan_, run, background_first_, number, total_), number, 0,
      0);
  if (inner_) return inner_->PrepareHallRecording(run);
  confirmed_ns_ = options_.host_clock_ns();
  return options_.mcu_device;
}

}  // namespace msmcal::live_view

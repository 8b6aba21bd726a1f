#include "sessions/orchestrator/setup_operator.h"

#include <optional>
#include <utility>

namespace msmcal::orchestrator {

SetupOperator::SetupOperator(const dataset::Recording& plan, SetupWalkOptions walk,
                             RigOperator* inner)
    : plan_(plan), inner_(inner), walk_(std::move(walk)) {
  setups_ = setup::PlanSetups(plan_, walk_.poses, /*background_first=*/false);
}

void SetupOperator::SeeFirstCall(bool is_background) {
  if (order_known_) return;
  order_known_ = true;
  if (is_background) setups_ = setup::PlanSetups(plan_, walk_.poses, true);
}

void SetupOperator::Enter(int k) {
  if (k == current_) return;
  Present(setups_.setups.at(static_cast<size_t>(k)));
  ++confirmations_;
  current_ = k;
}

void SetupOperator::Confirmed() { confirmed_ns_ = walk_.host_clock_ns(); }

void SetupOperator::PrepareStep1Frame(size_t index) {
  SeeFirstCall(false);
  Enter(setups_.step1_setup.at(index));
  if (inner_)
    inner_->PrepareStep1Frame(index);
  else
    Confirmed();
}

void SetupOperator::PrepareStep2Frame(size_t index) {
  SeeFirstCall(false);
  Enter(setups_.step2_setup.at(index));
  if (inner_)
    inner_->PrepareStep2Frame(index);
  else
    Confirmed();
}

bool SetupOperator::FrameShowsCurrentSetup(const camera::FrameInfo& info) const {
  if (inner_) return inner_->FrameShowsCurrentSetup(info);
  device_clock_.Observe(info);
  if (info.host_timestamp_ns - confirmed_ns_ < walk_.settle_ns) return false;
  if (walk_.exposure_ns <= 0 || info.device_timestamp_ns == 0) return true;
  const std::optional<int64_t> mark = device_clock_.HostNs(info.device_timestamp_ns);
  return !mark || *mark - walk_.exposure_ns >= confirmed_ns_ + walk_.device_margin_ns;
}

std::string SetupOperator::PrepareHallRecording(HallRun run) {
  SeeFirstCall(run == HallRun::kBackground);
  current_ = -1;  // a Hall set-up is always presented (its recording starts on the answer)
  Enter(run == HallRun::kBackground ? setups_.background_setup : setups_.actual_setup);
  if (inner_) return inner_->PrepareHallRecording(run);
  Confirmed();
  return walk_.mcu_device;
}

}  // namespace msmcal::orchestrator

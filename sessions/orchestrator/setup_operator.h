#pragma once
// The walk through a session's set-ups that every operator shares (console, hook, web page):
// the set-up plan (setup::PlanSetups) in the order the first call decides (the background Hall
// set-up first, or after step 1), one presentation per physical set-up (a frame at the set-up
// confirmed last is not presented again; a Hall set-up always is: its recording starts on the
// answer), then the inner operator (the demo's simulated world) or, in the lab, the freshness
// rule: a frame shows the set-up when it reached the host settle_ns after the confirmation and,
// when the camera stamps its frames, its exposure began after the confirmation on the camera's
// own clock (mapped onto the host's by camera::DeviceClockMap): a frame delivered late (a loaded
// host, a frame queued in the driver) was exposed earlier than its arrival says.
// Subclasses say only how a set-up is presented (Present).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "drivers/camera/device_clock.h"
#include "processing/dataset/recording.h"
#include "sessions/orchestrator/rig_operator.h"
#include "sessions/setup/setup.h"

namespace msmcal::orchestrator {

struct SetupWalkOptions {
  std::vector<setup::PoseGeometry> poses;  // per step-1 pose index, for the texts
  // Lab only (no inner operator): the MCU's device for both recordings, the camera driver's host
  // clock (ns) read at each confirmation, and the settle time after it.
  std::string mcu_device;
  std::function<int64_t()> host_clock_ns;
  int64_t settle_ns = 300'000'000;
  // The exposure's length, at most (ns; the camera's exposure, or its frame period when the
  // camera chooses). A frame counts only when (its device timestamp on the host clock) -
  // exposure_ns >= confirmation + device_margin_ns; 0: that check is off (host rule alone).
  int64_t exposure_ns = 0;
  // Covers the delivery delay of the fastest frame, by which mapped device times run late.
  int64_t device_margin_ns = 100'000'000;
};

class SetupOperator : public RigOperator {
 public:
  void PrepareStep1Frame(size_t index) final;
  void PrepareStep2Frame(size_t index) final;
  bool FrameShowsCurrentSetup(const camera::FrameInfo& info) const override;
  std::string PrepareHallRecording(HallRun run) final;

  // The plan's set-ups in the order decided by the first call.
  const setup::SetupPlan& setups() const { return setups_; }
  int total_steps() const { return static_cast<int>(setups_.setups.size()); }
  int confirmations() const { return confirmations_; }  // set-ups presented and confirmed

 protected:
  // `plan` and `inner` (may be null: lab) must outlive the operator.
  SetupOperator(const dataset::Recording& plan, SetupWalkOptions walk, RigOperator* inner);
  // Presents `s` to whoever changes the rig and returns once it is in place; throws to abort.
  virtual void Present(const setup::Setup& s) = 0;

  const dataset::Recording& plan_;
  RigOperator* inner_;

 private:
  void SeeFirstCall(bool is_background);
  void Enter(int k);
  void Confirmed();

  SetupWalkOptions walk_;
  setup::SetupPlan setups_;
  bool order_known_ = false;
  int current_ = -1;  // the set-up confirmed last (index into setups_.setups)
  int confirmations_ = 0;
  int64_t confirmed_ns_ = 0;
  // Fed every frame the orchestrator asks about (stale ones included: they are the fast ones).
  mutable camera::DeviceClockMap device_clock_;
};

}  // namespace msmcal::orchestrator

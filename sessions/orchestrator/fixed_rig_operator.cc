#include "sessions/orchestrator/fixed_rig_operator.h"

#include <algorithm>

namespace msmcal::orchestrator {

namespace {

std::string Ints(const std::vector<int>& v) {
  std::string s;
  for (int i : v) s += (s.empty() ? "" : ", ") + std::to_string(i);
  return "[" + s + "]";
}

std::string YesNo(bool b) { return b ? "true" : "false"; }

SetupWalkOptions WalkOf(const FixedRigOptions& o) {
  if (std::string e = o.Validate(); !e.empty()) throw std::invalid_argument(e);
  return {/*poses=*/{}, o.mcu_device, o.host_clock_ns, o.settle_ns, o.exposure_ns};
}

}  // namespace

std::string FixedRigOptions::Validate() const {
  if (mcu_device.empty()) return "FixedRigOptions.mcu_device = '': the Hall MCU's device is needed";
  if (!host_clock_ns) return "FixedRigOptions.host_clock_ns = (none): required";
  if (settle_ns < 0)
    return "FixedRigOptions.settle_ns = " + std::to_string(settle_ns) + ": must be >= 0";
  return {};
}

setup::RigState FixedRigState(const dataset::Recording& plan) {
  setup::RigState s;
  s.camera = "C2";
  s.msm_mounted = true;
  s.top_frame_mounted = true;
  s.sliding_plate = {};
  for (const auto& b : plan.beams) s.beams_unblocked.push_back(b.id);
  std::sort(s.beams_unblocked.begin(), s.beams_unblocked.end());
  return s;
}

setup::Setup FixedRigSetup(const dataset::Recording& plan) {
  setup::Setup s;
  s.block = 1;
  s.of = 1;
  s.step = setup::SetupStep::kStep2;
  s.state = FixedRigState(plan);
  s.drive = setup::Drive::kScan;
  s.changes = {"camera at the step-2 position C2 (sees the world board)",
               "mount the MSM in the beam path, with its top frame", "remove the sliding plate",
               "unblock beams " + Ints(s.state.beams_unblocked)};
  s.text = "=== [1/1] Rig sweep: the rig stays like this for every point ===\n";
  for (size_t i = 0; i < s.changes.size(); ++i)
    s.text += "  " + std::to_string(i + 1) + ". " + s.changes[i] + "\n";
  s.text += "Nobody touches the rig from here on: each point changes only the generators.\n";
  return s;
}

FixedRigOperator::FixedRigOperator(const dataset::Recording& plan, const FixedRigOptions& options)
    : SetupOperator(plan, WalkOf(options), /*inner=*/nullptr), state_(FixedRigState(plan)) {}

void FixedRigOperator::Present(const setup::Setup& s) {
  const std::string what = "set-up " + std::to_string(s.block) + "/" + std::to_string(s.of) + " (" +
                           setup::ToString(s.step) + ")";
  if (s.step == setup::SetupStep::kStep1 || s.step == setup::SetupStep::kHallBackground)
    throw FixedRigMismatch(what +
                           ": the rig stays in the step 2 state (nobody at the rig); step 1 and "
                           "the background Hall recording must come from the reference session");
  auto mismatch = [&](const std::string& field, const std::string& wanted,
                      const std::string& fixed) {
    throw FixedRigMismatch(what + " needs " + field + " = " + wanted + ", but the rig stays at " +
                           fixed + " (nobody at the rig)");
  };
  if (s.state.camera != state_.camera) mismatch("camera", s.state.camera, state_.camera);
  if (s.state.msm_mounted != state_.msm_mounted)
    mismatch("msm_mounted", YesNo(s.state.msm_mounted), YesNo(state_.msm_mounted));
  if (s.state.top_frame_mounted != state_.top_frame_mounted)
    mismatch("top_frame_mounted", YesNo(s.state.top_frame_mounted),
             YesNo(state_.top_frame_mounted));
  if (s.state.sliding_plate.mounted) mismatch("sliding_plate.mounted", "true", "false");
  // A Hall recording's beams are what the previous set-up left (it needs no dot); a frame's
  // beams are physical.
  if (s.step == setup::SetupStep::kStep2 && s.state.beams_unblocked != state_.beams_unblocked)
    mismatch("beams_unblocked", Ints(s.state.beams_unblocked), Ints(state_.beams_unblocked));
}

}  // namespace msmcal::orchestrator

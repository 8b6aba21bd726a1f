#pragma once
// Nobody at the rig (a rig sweep's point, docs/lab-path.md "Rig sweeps"): the rig stays in the
// step 2 state for the whole session part — MSM mounted with its top frame, camera at C2, no
// sliding plate, every beam of the plan unblocked — and the only changes are the generators'
// (drives, laser pattern). FixedRigOperator never prompts: every set-up the orchestrator walks
// through (SetupOperator) is checked against that state, and one that needs another (a step 1
// frame, the background Hall recording, a step 2 frame with beams blocked) throws
// FixedRigMismatch naming the set-up, the field and both values (RunSession then goes to the
// safe state). Frames count when they reached the host settle_ns after the frame's Prepare call
// (the lab freshness rule: the drive's settle is the orchestrator's). Both Hall recordings are
// on `mcu_device`.
//
// Thread safety: called from the orchestrator's thread only.

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>

#include "processing/dataset/recording.h"
#include "sessions/orchestrator/setup_operator.h"
#include "sessions/setup/setup.h"

namespace msmcal::orchestrator {

class FixedRigMismatch : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct FixedRigOptions {
  std::string mcu_device;                  // required
  std::function<int64_t()> host_clock_ns;  // the camera driver's host clock; required
  int64_t settle_ns = 300'000'000;         // >= 0
  int64_t exposure_ns = 0;  // as SetupWalkOptions::exposure_ns (0: host rule alone)
  std::string Validate() const;            // empty when valid; names field, value, constraint
};

// The state the rig stays in for `plan` (drive kScan: informative, the drives are the
// generators').
setup::RigState FixedRigState(const dataset::Recording& plan);
// The one set-up that puts the rig into FixedRigState (block 1 of 1, every change listed, a
// text for a person): what a hook (the twin's `msmcal mock hands`) receives once before a
// sweep's first point.
setup::Setup FixedRigSetup(const dataset::Recording& plan);

class FixedRigOperator : public SetupOperator {
 public:
  // `plan` must outlive the operator. Throws std::invalid_argument when options.Validate() fails.
  FixedRigOperator(const dataset::Recording& plan, const FixedRigOptions& options);

 private:
  void Present(const setup::Setup& s) override;  // checks; never prompts

  setup::RigState state_;
};

}  // namespace msmcal::orchestrator

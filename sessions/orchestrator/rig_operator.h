#pragma once
// What the orchestrator asks of the person at the rig (or of the simulated world standing in
// for the rig). In the lab these are prompts ("mount the sliding plate at pose 3, unblock beams
// 1 and 4"); in the demo they set a SimulatedWorld that the mock instruments read.

#include <cstddef>
#include <string>

#include "drivers/camera/camera.h"

namespace msmcal::orchestrator {

enum class HallRun { kBackground, kActual };
inline const char* ToString(HallRun run) {  // "background" | "actual"
  return run == HallRun::kBackground ? "background" : "actual";
}

class RigOperator {
 public:
  virtual ~RigOperator() = default;
  // Sets the rig up for step1_frames()[i] of the session plan (sliding plate pose, unblocked
  // beams, MSM not mounted) and returns when it is in place.
  virtual void PrepareStep1Frame(size_t index) = 0;
  // Sets the rig up for step2_frames()[i] (MSM mounted, drive mode, unblocked beams).
  virtual void PrepareStep2Frame(size_t index) = 0;
  // True when a received frame was exposed after the last Prepare*Frame() took effect (frames
  // already in flight when the rig changed must be discarded).
  virtual bool FrameShowsCurrentSetup(const camera::FrameInfo& info) const = 0;
  // Sets the rig up for a Hall recording (background: mirror top frame removed, coils driven;
  // actual: mirror assembled, scanning) and returns the MCU's serial device path.
  virtual std::string PrepareHallRecording(HallRun run) = 0;
};

}  // namespace msmcal::orchestrator

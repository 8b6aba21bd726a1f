#pragma once
// The simulated "physical world" of the demo: which frame of the rig simulator's plan is set up
// (sliding plate pose, unblocked beams, MSM mounted, drive mode) and which Hall recording the MCU
// sees. The mock camera's frame source and the mock MCUs read it; the orchestrator's operator
// actions set it (RigOperator).
//
// Frame freshness: the frame source tags each frame it fills with the world's generation,
// keyed by the frame's device timestamp (the same value the GigE Vision client receives), so
// FrameShowsCurrentSetup() can reject frames rendered before the last change.

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include "mocks/camera/mock_gv_camera.h"
#include "mocks/camera/rig_scene_source.h"
#include "mocks/rig/rig_simulator.h"
#include "sessions/orchestrator/rig_operator.h"

namespace msmcal::twin {

class SimulatedWorld : public orchestrator::RigOperator {
 public:
  // `hall_device` returns the device path of a mock MCU streaming the given recording (the demo
  // rig starts one per recording).
  SimulatedWorld(std::shared_ptr<const sim::RigSimulator> sim,
                 std::function<std::string(orchestrator::HallRun)> hall_device);

  // The frame source for the mock camera (renders the scene of the current setup).
  sim::FrameSource MakeFrameSource();

  void PrepareStep1Frame(size_t index) override;
  void PrepareStep2Frame(size_t index) override;
  bool FrameShowsCurrentSetup(const camera::FrameInfo& info) const override;
  std::string PrepareHallRecording(orchestrator::HallRun run) override;

  const sim::RigSimulator& sim() const { return *sim_; }
  uint64_t generation() const;

 private:
  void Set(sim::RigFrameRef ref);

  std::shared_ptr<const sim::RigSimulator> sim_;
  std::function<std::string(orchestrator::HallRun)> hall_device_;
  mutable std::mutex mu_;
  sim::RigFrameRef ref_{1, 0};
  uint64_t generation_ = 0;
  // (device timestamp ns, generation) of the most recently filled frames.
  std::deque<std::pair<int64_t, uint64_t>> filled_;
};

}  // namespace msmcal::twin

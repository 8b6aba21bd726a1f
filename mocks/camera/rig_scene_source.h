#pragma once
// Frames of the simulated rig for the mock camera: the rig simulator's scenes rendered by the
// renderer (mocks/render), at the simulator camera's resolution (serve the mock with that sensor
// size so pixels match the simulator's camera model and ground truth).

#include <cstdint>
#include <functional>
#include <memory>

#include "mocks/camera/mock_gv_camera.h"
#include "mocks/rig/rig_simulator.h"

namespace msmcal::sim {

// Which of the simulator's recorded frames the camera shows.
struct RigFrameRef {
  int step = 2;      // 1: step1_frames(), 2: step2_frames()
  size_t index = 0;  // index into that list
};

// Default selection: step 1 frames, then step 2 frames, then again (frame_index modulo the
// total). An orchestrator or generator mock passes its own (e.g. the current step and the
// trigger pattern in force); it is called on the camera thread.
RigFrameRef CycleThroughFrames(const RigSimulator& sim, uint64_t frame_index);

// Renders the selected scene for each frame (re-rendering only when the selection changes; the
// render is deterministic for the simulator's seed). Throws std::invalid_argument if the
// simulator has no frames.
FrameSource MakeRigSceneSource(std::shared_ptr<const RigSimulator> sim,
                               std::function<RigFrameRef(uint64_t frame_index)> select = {});

}  // namespace msmcal::sim

#include "simulation/twin/simulated_world.h"

#include <stdexcept>

namespace msmcal::twin {

SimulatedWorld::SimulatedWorld(std::shared_ptr<const sim::RigSimulator> sim,
                               std::function<std::string(orchestrator::HallRun)> hall_device)
    : sim_(std::move(sim)), hall_device_(std::move(hall_device)) {
  if (!sim_) throw std::invalid_argument("SimulatedWorld: no simulator");
}

sim::FrameSource SimulatedWorld::MakeFrameSource() {
  // The selection for the frame being filled: read together with the generation, before the
  // render (the camera thread fills one frame at a time).
  auto current = std::make_shared<sim::RigFrameRef>();
  sim::FrameSource inner =
      sim::MakeRigSceneSource(sim_, [current](uint64_t /*frame_index*/) { return *current; });
  return [this, current, inner](uint8_t* data, int width, int height, sim::SimPixelFormat fmt,
                                int64_t timestamp_ns, uint64_t frame_index) {
    uint64_t generation = 0;
    {
      std::lock_guard<std::mutex> lock(mu_);
      *current = ref_;
      generation = generation_;
    }
    inner(data, width, height, fmt, timestamp_ns, frame_index);
    std::lock_guard<std::mutex> lock(mu_);
    filled_.emplace_back(timestamp_ns, generation);
    while (filled_.size() > 256) filled_.pop_front();
  };
}

void SimulatedWorld::Set(sim::RigFrameRef ref) {
  std::lock_guard<std::mutex> lock(mu_);
  ref_ = ref;
  ++generation_;
}

void SimulatedWorld::PrepareStep1Frame(size_t index) {
  if (index >= sim_->step1_frames().size())
    throw std::out_of_range("SimulatedWorld: step 1 frame " + std::to_string(index));
  Set({1, index});
}

void SimulatedWorld::PrepareStep2Frame(size_t index) {
  if (index >= sim_->step2_frames().size())
    throw std::out_of_range("SimulatedWorld: step 2 frame " + std::to_string(index));
  Set({2, index});
}

bool SimulatedWorld::FrameShowsCurrentSetup(const camera::FrameInfo& info) const {
  std::lock_guard<std::mutex> lock(mu_);
  for (auto it = filled_.rbegin(); it != filled_.rend(); ++it) {
    if (it->first == info.device_timestamp_ns) return it->second == generation_;
  }
  return false;
}

std::string SimulatedWorld::PrepareHallRecording(orchestrator::HallRun run) {
  return hall_device_(run);
}

uint64_t SimulatedWorld::generation() const {
  std::lock_guard<std::mutex> lock(mu_);
  return generation_;
}

}  // namespace msmcal::twin

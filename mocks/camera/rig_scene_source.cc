#include "mocks/camera/rig_scene_source.h"

#include <mutex>
#include <stdexcept>

#include "mocks/camera/place_image.h"

namespace msmcal::sim {

RigFrameRef CycleThroughFrames(const RigSimulator& sim, uint64_t frame_index) {
  const size_t n1 = sim.step1_frames().size();
  const size_t n2 = sim.step2_frames().size();
  const size_t k = static_cast<size_t>(frame_index % (n1 + n2));
  if (k < n1) return {1, k};
  return {2, k - n1};
}

FrameSource MakeRigSceneSource(std::shared_ptr<const RigSimulator> sim,
                               std::function<RigFrameRef(uint64_t frame_index)> select) {
  if (!sim || sim->step1_frames().size() + sim->step2_frames().size() == 0) {
    throw std::invalid_argument("rig scene source: the simulator has no frames");
  }
  if (!select) {
    select = [raw = sim.get()](uint64_t frame_index) {
      return CycleThroughFrames(*raw, frame_index);
    };
  }
  struct Cache {
    std::mutex mutex;
    bool valid = false;
    RigFrameRef ref;
    cv::Mat image;
  };
  auto cache = std::make_shared<Cache>();
  return [sim, select, cache](uint8_t* data, int width, int height, SimPixelFormat fmt,
                              int64_t /*timestamp_ns*/, uint64_t frame_index) {
    const RigFrameRef ref = select(frame_index);
    std::lock_guard<std::mutex> lock(cache->mutex);
    if (!cache->valid || cache->ref.step != ref.step || cache->ref.index != ref.index) {
      cache->image =
          ref.step == 1 ? sim->RenderStep1Frame(ref.index) : sim->RenderStep2Frame(ref.index);
      cache->ref = ref;
      cache->valid = true;
    }
    PlaceImage(cache->image, data, width, height, fmt);
  };
}

}  // namespace msmcal::sim

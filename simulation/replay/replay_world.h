#pragma once
// The "physical world" of a replay: a recorded session folder standing in for the rig. Each
// Prepare*Frame(i) selects the image recorded for plan.step1[i] / plan.step2[i] — the accepted
// image at its interchange path (step1/0003.png), or, for a frame the original run rejected, the
// image it kept as rejected/step1_0003.png — and the mock camera's frame source serves it.
// PrepareHallRecording() returns the device of a mock MCU replaying the recorded Hall file.
//
// Frame freshness as in SimulatedWorld: the frame source tags each frame it fills with the
// world's generation, keyed by the frame's device timestamp, so FrameShowsCurrentSetup() rejects
// frames filled before the last change.
//
// Thread safety: Prepare*/FrameShowsCurrentSetup run on the orchestrator's thread, the frame
// source on the camera's thread; the shared state is behind a mutex.

#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

#include "mocks/camera/mock_gv_camera.h"
#include "processing/dataset/recording.h"
#include "sessions/orchestrator/rig_operator.h"

namespace msmcal::replay {

// Where the original run left the image of frame `file` ("step1/0003.png"): `source/file` if it
// exists, else `source/rejected/step1_0003.png` if that exists, else empty.
std::filesystem::path RecordedImagePath(const std::filesystem::path& source,
                                        const std::string& file);

class ReplayWorld : public orchestrator::RigOperator {
 public:
  // Resolves every frame's recorded image now. Throws std::runtime_error naming the missing file
  // (and the rejected/ name it also looked for) when one of plan's frames has no image.
  ReplayWorld(std::filesystem::path source, const dataset::Recording& plan,
              std::function<std::string(orchestrator::HallRun)> hall_device);

  // The frame source for the mock camera: the current frame's image placed top-left (converted
  // to the requested pixel format), black before the first Prepare*Frame().
  sim::FrameSource MakeFrameSource();

  // Load the recorded image (throws std::runtime_error naming it when it cannot be decoded).
  void PrepareStep1Frame(size_t index) override;
  void PrepareStep2Frame(size_t index) override;
  bool FrameShowsCurrentSetup(const camera::FrameInfo& info) const override;
  std::string PrepareHallRecording(orchestrator::HallRun run) override;

  const std::vector<std::filesystem::path>& step1_images() const { return step1_images_; }
  const std::vector<std::filesystem::path>& step2_images() const { return step2_images_; }
  uint64_t generation() const;

 private:
  void Show(const std::filesystem::path& image);

  std::filesystem::path source_;
  std::vector<std::filesystem::path> step1_images_, step2_images_;
  std::function<std::string(orchestrator::HallRun)> hall_device_;
  mutable std::mutex mu_;
  std::shared_ptr<const cv::Mat> image_;  // null: black
  uint64_t generation_ = 0;
  // (device timestamp ns, generation) of the most recently filled frames.
  std::deque<std::pair<int64_t, uint64_t>> filled_;
};

}  // namespace msmcal::replay

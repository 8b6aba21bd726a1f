// The rig-scene frame source serves exactly the simulator's rendered frames.
#include "mocks/camera/rig_scene_source.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

namespace msmcal::sim {
namespace {

std::shared_ptr<RigSimulator> SmallRig() {
  SimOptions options;  // paper-like defaults, with a small camera to keep the test fast
  options.camera.width = 612;
  options.camera.height = 512;
  options.camera.fx = options.camera.fy = 500;
  options.camera.cx = 305.5;
  options.camera.cy = 255.5;
  return std::make_shared<RigSimulator>(options);
}

TEST(RigSceneSource, ServesTheSimulatorsFramesInOrder) {
  auto sim = SmallRig();
  FrameSource source = MakeRigSceneSource(sim);
  const int w = sim->camera().width, h = sim->camera().height;
  std::vector<uint8_t> frame(static_cast<size_t>(w) * h);
  const size_t n1 = sim->step1_frames().size();
  ASSERT_GT(n1, 0u);
  ASSERT_GT(sim->step2_frames().size(), 0u);
  for (const auto& [index, expected] :
       {std::pair<uint64_t, cv::Mat>{0, sim->RenderStep1Frame(0)},
        std::pair<uint64_t, cv::Mat>{n1, sim->RenderStep2Frame(0)}}) {
    source(frame.data(), w, h, SimPixelFormat::kMono8, 0, index);
    ASSERT_EQ(expected.type(), CV_8UC1);  // default options render mono
    const cv::Mat got(h, w, CV_8UC1, frame.data());
    EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0) << "frame " << index;
  }
  const RigFrameRef wrapped = CycleThroughFrames(*sim, n1 + sim->step2_frames().size());
  EXPECT_EQ(wrapped.step, 1);
  EXPECT_EQ(wrapped.index, 0u);
}

}  // namespace
}  // namespace msmcal::sim

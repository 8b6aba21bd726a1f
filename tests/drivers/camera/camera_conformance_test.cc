// One conformance suite for the Camera interface, run against every implementation:
//   - V4L2 driver on the fake V4L2 device (always),
//   - Aravis driver on Aravis's own `arv-fake-gv-camera-0.8 -i 127.0.0.1` (a camera we did not
//     write; skipped with a message where aravis-tools is absent),
//   - Aravis driver on our mock GigE Vision camera (MockGvCamera, test pattern).
// Runs under tests/drivers/camera/netns_exec.sh: a private network namespace per test process.
#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "drivers/camera/aravis_camera.h"
#include "drivers/camera/camera.h"
#include "drivers/camera/testing/fake_v4l2_device.h"
#include "drivers/camera/testing/subprocess.h"
#include "drivers/camera/v4l2_camera.h"
#include "mocks/camera/mock_gv_camera.h"

namespace msmcal::camera {
namespace {

using testing::FakeV4l2Device;
using testing::ProgramInPath;
using testing::Subprocess;

// Opens by address, retrying until the server answers or the deadline passes (a server that just
// started may not have bound its port yet; each failed open itself waits ~2.5 s for an answer).
OpenCameraResult OpenAravisWithDeadline(const std::string& address, int64_t deadline_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(deadline_ms);
  AravisCameraOptions options;
  options.device = address;
  OpenCameraResult opened;
  do {
    opened = OpenAravisCamera(options);
  } while (!opened.camera && std::chrono::steady_clock::now() < deadline);
  return opened;
}

struct Fixture {
  std::unique_ptr<Camera> camera;
  // Checks that a frame's bytes are whole (empty = content not checkable).
  std::function<bool(const Frame&)> content_ok;
  // Everything the camera needs alive (fake device, mock server, child process).
  std::shared_ptr<void> keep_alive;
  std::function<void()> unplug;
  std::string skip_reason;
};

struct Implementation {
  std::string name;
  std::function<Fixture()> make;
};

Fixture MakeV4l2() {
  Fixture f;
  auto fake = std::make_shared<FakeV4l2Device>();
  fake->SetAutoProduce(true);
  V4l2CameraOptions options;
  options.syscalls = fake;
  OpenCameraResult opened = OpenV4l2Camera(options);
  f.camera = std::move(opened.camera);
  f.keep_alive = fake;
  f.unplug = [fake] { fake->Unplug(); };
  f.content_ok = [](const Frame& frame) {
    uint64_t seq = 0;
    for (int i = 0; i < 8; ++i) seq |= static_cast<uint64_t>(frame.data()[i]) << (8 * i);
    for (size_t i = 0; i < frame.size_bytes(); i += 331) {
      if (frame.data()[i] != FakeV4l2Device::PatternByte(seq, i)) return false;
    }
    return true;
  };
  return f;
}

Fixture MakeAravisFake() {
  Fixture f;
  if (!ProgramInPath("arv-fake-gv-camera-0.8")) {
    f.skip_reason = "arv-fake-gv-camera-0.8 not installed (Debian package aravis-tools)";
    return f;
  }
  auto server = std::make_shared<Subprocess>(
      std::vector<std::string>{"arv-fake-gv-camera-0.8", "-i", "127.0.0.1"});
  OpenCameraResult opened = OpenAravisWithDeadline("127.0.0.1", 10000);
  f.camera = std::move(opened.camera);
  if (!f.camera) f.skip_reason.clear();
  f.keep_alive = server;
  f.unplug = [server] { server->Kill(); };
  return f;
}

Fixture MakeAravisMock() {
  Fixture f;
  sim::MockGvCameraOptions options;
  options.sensor_width = 1280;
  options.sensor_height = 960;
  std::string error;
  std::shared_ptr<sim::MockGvCamera> server =
      sim::MockGvCamera::Start(options, sim::MakeTestPatternSource(), &error);
  if (!server) return f;
  OpenCameraResult opened = OpenAravisWithDeadline("127.0.0.1", 10000);
  f.camera = std::move(opened.camera);
  auto holder = std::make_shared<std::shared_ptr<sim::MockGvCamera>>(server);
  f.keep_alive = holder;
  f.unplug = [holder] { holder->reset(); };
  f.content_ok = [](const Frame& frame) {
    uint64_t index = 0;
    for (int i = 0; i < 8; ++i) index |= static_cast<uint64_t>(frame.data()[i]) << (8 * i);
    for (size_t i = 0; i < frame.size_bytes(); i += 331) {
      if (frame.data()[i] != sim::PatternByte(index, i)) return false;
    }
    return true;
  };
  return f;
}

class CameraConformance : public ::testing::TestWithParam<Implementation> {
 protected:
  void SetUp() override {
    fixture_ = GetParam().make();
    if (!fixture_.skip_reason.empty()) GTEST_SKIP() << fixture_.skip_reason;
    ASSERT_TRUE(fixture_.camera) << GetParam().name << ": camera did not open";
  }
  void TearDown() override {
    if (fixture_.camera) fixture_.camera->Stop();
    fixture_.camera.reset();
  }
  CameraConfig Config640() {
    CameraConfig config;
    config.pixel_format = PixelFormat::kMono8;
    config.roi.width = 640;
    config.roi.height = 480;
    config.frame_rate_hz = 50;
    config.buffer_count = 8;
    return config;
  }
  Fixture fixture_;
};

TEST_P(CameraConformance, ReportsInfo) {
  const CameraInfo info = fixture_.camera->Info();
  EXPECT_GE(info.sensor_width, 640);
  EXPECT_GE(info.sensor_height, 480);
  EXPECT_NE(std::find(info.pixel_formats.begin(), info.pixel_formats.end(), PixelFormat::kMono8),
            info.pixel_formats.end());
}

TEST_P(CameraConformance, RejectsInvalidConfigNamingTheField) {
  CameraConfig config = Config640();
  config.buffer_count = 1;
  Status s = fixture_.camera->Configure(config);
  EXPECT_FALSE(s);
  EXPECT_NE(s.message.find("buffer_count = 1"), std::string::npos) << s.message;
}

TEST_P(CameraConformance, NotStreamingBeforeStart) {
  EXPECT_EQ(fixture_.camera->NextFrame(1000).status, FrameStatus::kNotStreaming);
}

TEST_P(CameraConformance, StreamsCompleteFramesWithZeroFailures) {
  Camera& camera = *fixture_.camera;
  ASSERT_TRUE(camera.Configure(Config640()));
  ASSERT_TRUE(camera.Start());
  uint64_t last_id = 0;
  for (int k = 0; k < 20; ++k) {
    FrameResult r = camera.NextFrame(3'000'000);
    ASSERT_EQ(r.status, FrameStatus::kOk) << r.message;
    const FrameInfo& info = r.frame.info();
    EXPECT_EQ(info.width, 640);
    EXPECT_EQ(info.height, 480);
    EXPECT_EQ(info.pixel_format, PixelFormat::kMono8);
    EXPECT_EQ(r.frame.size_bytes(), 640u * 480u);
    if (k > 0) {
      EXPECT_GT(info.frame_id, last_id);
    }
    last_id = info.frame_id;
    if (fixture_.content_ok) {
      EXPECT_TRUE(fixture_.content_ok(r.frame)) << "frame " << k;
    }
  }
  const StreamStats stats = camera.Stats();
  EXPECT_GE(stats.completed, 20u);
  EXPECT_EQ(stats.failed, 0u);
  EXPECT_EQ(stats.missing_packets, 0u);
  EXPECT_EQ(stats.missing_frames, 0u);
}

TEST_P(CameraConformance, HeldFramesOutliveStopAndRestartWorks) {
  Camera& camera = *fixture_.camera;
  ASSERT_TRUE(camera.Configure(Config640()));
  ASSERT_TRUE(camera.Start());
  FrameResult held = camera.NextFrame(3'000'000);
  ASSERT_EQ(held.status, FrameStatus::kOk) << held.message;
  camera.Stop();
  if (fixture_.content_ok) {
    EXPECT_TRUE(fixture_.content_ok(held.frame));
  }
  held.frame.Reset();
  ASSERT_TRUE(camera.Start());
  FrameResult again = camera.NextFrame(3'000'000);
  EXPECT_EQ(again.status, FrameStatus::kOk) << again.message;
}

TEST_P(CameraConformance, ReportsLossOfTheCamera) {
  Camera& camera = *fixture_.camera;
  ASSERT_TRUE(camera.Configure(Config640()));
  ASSERT_TRUE(camera.Start());
  ASSERT_EQ(camera.NextFrame(3'000'000).status, FrameStatus::kOk);
  fixture_.unplug();
  // After the loss no frame is complete; the driver reports timeouts and then the loss.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  FrameStatus status = FrameStatus::kOk;
  int frames_after = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    FrameResult r = camera.NextFrame(500'000);
    status = r.status;
    if (status == FrameStatus::kOk) ++frames_after;  // frames already in flight
    if (status == FrameStatus::kDisconnected) break;
  }
  EXPECT_EQ(status, FrameStatus::kDisconnected);
  EXPECT_LE(frames_after, 8);
}

// The rig camera's size: 10 MP frames through GigE Vision on loopback, none lost or torn.
TEST(AravisCamera, StreamsTenMegapixelFramesFromTheMockWithZeroFailures) {
  sim::MockGvCameraOptions options;  // 3840 x 2748
  std::string error;
  auto server = sim::MockGvCamera::Start(options, sim::MakeTestPatternSource(), &error);
  ASSERT_TRUE(server) << error;
  OpenCameraResult opened = OpenAravisWithDeadline("127.0.0.1", 10000);
  ASSERT_TRUE(opened.camera) << opened.error;
  Camera& camera = *opened.camera;
  EXPECT_EQ(camera.Info().sensor_width, 3840);
  EXPECT_EQ(camera.Info().sensor_height, 2748);
  CameraConfig config;
  config.frame_rate_hz = 5;
  config.buffer_count = 4;
  ASSERT_TRUE(camera.Configure(config));
  ASSERT_TRUE(camera.Start());
  for (int k = 0; k < 6; ++k) {
    FrameResult r = camera.NextFrame(5'000'000);
    ASSERT_EQ(r.status, FrameStatus::kOk) << r.message;
    ASSERT_EQ(r.frame.size_bytes(), 3840u * 2748u);
    uint64_t index = 0;
    for (int i = 0; i < 8; ++i) index |= static_cast<uint64_t>(r.frame.data()[i]) << (8 * i);
    for (size_t i = 0; i < r.frame.size_bytes(); i += 4093) {
      ASSERT_EQ(r.frame.data()[i], sim::PatternByte(index, i)) << "frame " << k << " byte " << i;
    }
  }
  camera.Stop();
  const StreamStats stats = camera.Stats();
  EXPECT_EQ(stats.failed, 0u);
  EXPECT_EQ(stats.missing_packets, 0u);
}

INSTANTIATE_TEST_SUITE_P(
    AllCameras, CameraConformance,
    ::testing::Values(Implementation{"V4l2FakeDevice", MakeV4l2},
                      Implementation{"AravisOnArvFakeGvCamera", MakeAravisFake},
                      Implementation{"AravisOnMockGvCamera", MakeAravisMock}),
    [](const ::testing::TestParamInfo<Implementation>& info) { return info.param.name; });

}  // namespace
}  // namespace msmcal::camera

// A session whose camera is a V4L2 device, opened by the orchestrator through the drivers'
// InstrumentFactory (camera::OpenCamera with "v4l2:DEVICE"): the in-process fake V4L2 device
// behind the driver's syscall seam (no /dev/video* exists on our machines), the generators and
// the Hall MCU served by the demo rig's mocks. The fake's frames are a test pattern (no boards),
// so the quality gate is off and every frame counts as showing the current setup; the session
// is the shortest the orchestrator allows with the tiny simulated plan.
// Runs in its own network namespace (the demo rig's mock camera serves GigE Vision on port 3956).

#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "drivers/camera/testing/fake_v4l2_device.h"
#include "mocks/generator/mock_server.h"
#include "sessions/orchestrator/instruments.h"
#include "sessions/orchestrator/orchestrator.h"
#include "simulation/twin/demo_rig.h"
#include "tests/testing/tiny_sim.h"

namespace msmcal::orchestrator {
namespace {

namespace fs = std::filesystem;
using camera::testing::FakeV4l2Device;

fs::path FreshDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("v4l2_session_" + name);
  fs::remove_all(dir);
  return dir;
}

// The demo world's operator actions (which also start the mock MCUs), with every frame taken as
// fresh: the fake device's frames carry no generation tag of the simulated world.
class AnyFrameOperator : public RigOperator {
 public:
  explicit AnyFrameOperator(RigOperator& world) : world_(world) {}
  void PrepareStep1Frame(size_t index) override { world_.PrepareStep1Frame(index); }
  void PrepareStep2Frame(size_t index) override { world_.PrepareStep2Frame(index); }
  bool FrameShowsCurrentSetup(const camera::FrameInfo&) const override { return true; }
  std::string PrepareHallRecording(HallRun run) override {
    return world_.PrepareHallRecording(run);
  }

 private:
  RigOperator& world_;
};

TEST(V4l2Session, ASessionRunsWithAV4l2CameraOpenedThroughTheFactory) {
  twin::DemoRigOptions ro;
  ro.sim = testing::TinySim();
  twin::DemoRig rig(ro);
  const dataset::Recording plan = rig.Plan();

  FakeV4l2Device::Options fo;
  fo.path = "/dev/video7";
  fo.formats = {{V4L2_PIX_FMT_GREY, 1, {{plan.camera.width, plan.camera.height}}}};
  auto device = std::make_shared<FakeV4l2Device>(fo);
  device->SetAutoProduce(true);

  const fs::path dir = FreshDir("complete");
  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir);
  options.camera = "v4l2:/dev/video7";
  DriverInstrumentOptions io;
  io.v4l2_syscalls = device;
  options.instruments = MakeDriverInstruments(io);
  options.run_quality_gate = false;  // a test pattern has no boards to gate on
  AnyFrameOperator op(rig.world());
  const SessionResult result = RunSession(options, plan, op, nullptr);

  EXPECT_TRUE(result.rig_check.ok);
  bool found_camera = false;
  for (const auto& [role, identity] : result.rig_check.instruments)
    if (role == "camera") {
      found_camera = true;
      EXPECT_NE(identity.find("msmcal fake V4L2 camera"), std::string::npos) << identity;
    }
  EXPECT_TRUE(found_camera);
  EXPECT_TRUE(result.safe_state_confirmed);
  EXPECT_FALSE(rig.generators().unit(1).AnyOutputOn());
  EXPECT_FALSE(rig.generators().unit(2).AnyOutputOn());
  ASSERT_EQ(result.frames.size(), plan.step1.size() + plan.step2.size());
  for (const auto& f : result.frames) EXPECT_TRUE(f.accepted) << f.file << ": " << f.reason;
  EXPECT_GT(result.actual_readings, 1000u);
  EXPECT_TRUE(fs::exists(dir / "session.yaml"));
  EXPECT_EQ(device->open_fds(), 0);  // the camera was closed when the session ended
  EXPECT_FALSE(device->streaming());

  // Every image on disk is, byte for byte, a frame the V4L2 device delivered: the fake's pattern
  // for the sequence number held in the frame's first 8 bytes.
  for (const auto& f : result.frames) {
    const cv::Mat image = cv::imread((dir / f.file).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(image.type(), CV_8UC1) << f.file;
    ASSERT_EQ(image.cols, plan.camera.width) << f.file;
    ASSERT_EQ(image.rows, plan.camera.height) << f.file;
    ASSERT_TRUE(image.isContinuous());
    const uint8_t* p = image.ptr<uint8_t>(0);
    uint64_t sequence = 0;
    for (int b = 0; b < 8; ++b) sequence |= static_cast<uint64_t>(p[b]) << (8 * b);
    const size_t n = image.total();
    size_t wrong = 0;
    for (size_t i = 8; i < n; i += 997) wrong += p[i] != FakeV4l2Device::PatternByte(sequence, i);
    EXPECT_EQ(wrong, 0u) << f.file << " (sequence " << sequence << ")";
  }
}

TEST(DriverInstruments, ASessionNeverOpensACameraByDiscovery) {
  const auto instruments = MakeDriverInstruments();
  const camera::OpenCameraResult r = instruments->OpenCamera("aravis:Fake_1");
  EXPECT_EQ(r.camera, nullptr);
  EXPECT_NE(r.error.find("by address only"), std::string::npos) << r.error;
}

TEST(DriverInstruments, AV4l2DeviceThatDoesNotExistIsNamed) {
  DriverInstrumentOptions io;
  io.v4l2_syscalls = std::make_shared<FakeV4l2Device>();  // serves /dev/video0 only
  const camera::OpenCameraResult r = MakeDriverInstruments(io)->OpenCamera("/dev/video3");
  EXPECT_EQ(r.camera, nullptr);
  EXPECT_NE(r.error.find("/dev/video3"), std::string::npos) << r.error;
}

}  // namespace
}  // namespace msmcal::orchestrator

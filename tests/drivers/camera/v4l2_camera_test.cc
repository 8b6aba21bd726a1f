// The V4L2 driver against the fake device behind the syscall seam (no /dev/video* exists on our
// machines), plus the driver-independent pieces of camera.h.
#include "drivers/camera/v4l2_camera.h"

#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <cerrno>
#include <thread>

#include "drivers/camera/camera.h"
#include "drivers/camera/testing/fake_v4l2_device.h"

namespace msmcal::camera {
namespace {

using testing::FakeV4l2Device;

TEST(PixelFormat, NamesRoundTripAndSizes) {
  for (PixelFormat f :
       {PixelFormat::kMono8, PixelFormat::kMono16, PixelFormat::kBayerRG8, PixelFormat::kRGB8}) {
    EXPECT_EQ(ParsePixelFormat(PixelFormatName(f)), f);
  }
  EXPECT_EQ(BytesPerPixel(PixelFormat::kMono16), 2);
  EXPECT_EQ(BytesPerPixel(PixelFormat::kRGB8), 3);
  EXPECT_FALSE(ParsePixelFormat("YUYV").has_value());
}

TEST(CameraConfig, ValidateNamesFieldValueAndConstraint) {
  CameraConfig config;
  EXPECT_EQ(config.Validate(), "");
  config.buffer_count = 1;
  EXPECT_EQ(config.Validate(), "CameraConfig.buffer_count = 1: must be in [2, 256]");
  config = {};
  config.exposure_us = -5;
  EXPECT_EQ(config.Validate(), "CameraConfig.exposure_us = -5: must be > 0");
}

TEST(FrameIdUnwrapper, GigEWrapSkipsZeroAndCountsGaps) {
  FrameIdUnwrapper u(65535, 1);
  EXPECT_EQ(u.Unwrap(65534), 65534u);
  EXPECT_EQ(u.Unwrap(65535), 65535u);
  EXPECT_EQ(u.Unwrap(1), 65536u);  // 65535 -> 1: one step, no gap
  EXPECT_EQ(u.skipped(), 0u);
  EXPECT_EQ(u.Unwrap(4), 65539u);  // 2 and 3 missing
  EXPECT_EQ(u.skipped(), 2u);
  EXPECT_EQ(u.Unwrap(4), 65539u);  // a repeat is the same frame
}

TEST(FrameIdUnwrapper, V4l2SequenceWrapsAt32Bits) {
  FrameIdUnwrapper u(uint64_t{1} << 32, 0);
  EXPECT_EQ(u.Unwrap(0xffffffffu), 0xffffffffu);
  EXPECT_EQ(u.Unwrap(0), 0x100000000u);
  EXPECT_EQ(u.skipped(), 0u);
}

TEST(Frame, OwnedFrameReleasesOnceAndMoves) {
  FrameInfo info;
  info.width = 2;
  info.height = 2;
  Frame a = Frame::Owned(info, {1, 2, 3, 4});
  Frame b = std::move(a);
  EXPECT_TRUE(a.empty());  // NOLINT(bugprone-use-after-move): moved-from state is specified
  ASSERT_FALSE(b.empty());
  EXPECT_EQ(b.data()[3], 4);
  EXPECT_EQ(b.stride_bytes(), 2u);
  b.Reset();
  EXPECT_TRUE(b.empty());
}

class V4l2CameraTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fake_ = std::make_shared<FakeV4l2Device>();
    V4l2CameraOptions options;
    options.path = "/dev/video0";
    options.syscalls = fake_;
    OpenCameraResult opened = OpenV4l2Camera(options);
    ASSERT_TRUE(opened.camera) << opened.error;
    camera_ = std::move(opened.camera);
  }
  void StartMono8(int buffers = 4) {
    CameraConfig config;
    config.buffer_count = buffers;
    ASSERT_TRUE(camera_->Configure(config));
    ASSERT_TRUE(camera_->Start());
  }
  static void ExpectPattern(const Frame& frame, uint64_t sequence) {
    for (size_t i = 0; i < frame.size_bytes(); i += 997) {
      ASSERT_EQ(frame.data()[i], FakeV4l2Device::PatternByte(sequence, i)) << "byte " << i;
    }
  }

  std::shared_ptr<FakeV4l2Device> fake_;
  std::unique_ptr<Camera> camera_;
};

TEST_F(V4l2CameraTest, InfoFromQuerycapAndEnumeration) {
  const CameraInfo info = camera_->Info();
  EXPECT_EQ(info.vendor, "msmcal_fake");
  EXPECT_EQ(info.sensor_width, 640);
  EXPECT_EQ(info.sensor_height, 480);
  EXPECT_EQ(info.pixel_formats, (std::vector<PixelFormat>{PixelFormat::kMono8, PixelFormat::kMono16,
                                                          PixelFormat::kRGB8}));
}

TEST_F(V4l2CameraTest, OpenMissingDeviceNamesPath) {
  V4l2CameraOptions options;
  options.path = "/dev/video7";
  options.syscalls = fake_;
  OpenCameraResult opened = OpenV4l2Camera(options);
  EXPECT_FALSE(opened.camera);
  EXPECT_NE(opened.error.find("/dev/video7: open"), std::string::npos) << opened.error;
}

TEST_F(V4l2CameraTest, NegotiatesFormatAndSnapsSize) {
  CameraConfig config;
  config.pixel_format = PixelFormat::kMono16;
  config.roi.width = 300;
  config.roi.height = 250;  // nearest offered: 320x240
  ASSERT_TRUE(camera_->Configure(config));
  EXPECT_EQ(fake_->current_fourcc(), V4L2_PIX_FMT_Y16);
  ASSERT_TRUE(camera_->Start());
  ASSERT_TRUE(fake_->ProduceFrame());
  FrameResult r = camera_->NextFrame(1000000);
  ASSERT_EQ(r.status, FrameStatus::kOk) << r.message;
  EXPECT_EQ(r.frame.info().width, 320);
  EXPECT_EQ(r.frame.info().height, 240);
  EXPECT_EQ(r.frame.info().pixel_format, PixelFormat::kMono16);
  EXPECT_EQ(r.frame.size_bytes(), 320u * 240u * 2u);
  ExpectPattern(r.frame, 0);
}

TEST_F(V4l2CameraTest, RejectsFormatTheDeviceDoesNotOffer) {
  CameraConfig config;
  config.pixel_format = PixelFormat::kBayerRG8;
  Status s = camera_->Configure(config);
  EXPECT_FALSE(s);
  EXPECT_NE(s.message.find("BayerRG8 not offered"), std::string::npos) << s.message;
  config.pixel_format = PixelFormat::kMono8;
  config.roi.x = 8;
  s = camera_->Configure(config);
  EXPECT_FALSE(s);
  EXPECT_NE(s.message.find("roi offset"), std::string::npos) << s.message;
}

TEST_F(V4l2CameraTest, StreamsFramesInOrderWithSequenceAndTimestamps) {
  StartMono8();
  EXPECT_TRUE(fake_->streaming());
  EXPECT_EQ(fake_->mapped_buffers(), 4);
  int64_t last_ts = -1;
  for (uint64_t k = 0; k < 10; ++k) {
    ASSERT_TRUE(fake_->ProduceFrame());
    FrameResult r = camera_->NextFrame(1000000);
    ASSERT_EQ(r.status, FrameStatus::kOk) << r.message;
    EXPECT_EQ(r.frame.info().frame_id, k);
    EXPECT_GT(r.frame.info().device_timestamp_ns, last_ts);
    last_ts = r.frame.info().device_timestamp_ns;
    ExpectPattern(r.frame, k);
  }
  EXPECT_EQ(camera_->Stats().completed, 10u);
  EXPECT_EQ(camera_->Stats().failed, 0u);
  camera_->Stop();
  EXPECT_FALSE(fake_->streaming());
  EXPECT_EQ(fake_->mapped_buffers(), 0);
}

TEST_F(V4l2CameraTest, TimesOutWhenNoFrameArrives) {
  StartMono8();
  FrameResult r = camera_->NextFrame(20000);
  EXPECT_EQ(r.status, FrameStatus::kTimeout);
}

TEST_F(V4l2CameraTest, NotStreamingBeforeStart) {
  EXPECT_EQ(camera_->NextFrame(1000).status, FrameStatus::kNotStreaming);
}

TEST_F(V4l2CameraTest, RetriesEagainAndCountsEio) {
  StartMono8();
  ASSERT_TRUE(fake_->ProduceFrame());
  fake_->FailIoctl(VIDIOC_DQBUF, EAGAIN, 2);
  FrameResult r = camera_->NextFrame(1000000);
  ASSERT_EQ(r.status, FrameStatus::kOk) << r.message;
  fake_->FailIoctl(VIDIOC_DQBUF, EIO, 1);
  ASSERT_TRUE(fake_->ProduceFrame());
  r = camera_->NextFrame(1000000);
  ASSERT_EQ(r.status, FrameStatus::kOk) << r.message;
  EXPECT_EQ(camera_->Stats().failed, 1u);
}

TEST_F(V4l2CameraTest, DropsErrorFlaggedAndShortBuffersAndRequeuesThem) {
  StartMono8(/*buffers=*/2);
  FakeV4l2Device::FrameFault flagged;
  flagged.error_flag = true;
  FakeV4l2Device::FrameFault short_frame;
  short_frame.short_bytes = 100;
  for (int round = 0; round < 3; ++round) {  // more rounds than buffers: they come back
    ASSERT_TRUE(fake_->ProduceFrame(flagged));
    ASSERT_TRUE(fake_->ProduceFrame(short_frame));
    EXPECT_EQ(camera_->NextFrame(20000).status, FrameStatus::kTimeout);
  }
  ASSERT_TRUE(fake_->ProduceFrame());
  FrameResult r = camera_->NextFrame(1000000);
  ASSERT_EQ(r.status, FrameStatus::kOk) << r.message;
  EXPECT_EQ(r.frame.info().frame_id, 6u);
  EXPECT_EQ(camera_->Stats().failed, 6u);
  EXPECT_EQ(camera_->Stats().completed, 1u);
}

TEST_F(V4l2CameraTest, CountsSequenceGapsAsMissingFrames) {
  StartMono8();
  ASSERT_TRUE(fake_->ProduceFrame());
  ASSERT_EQ(camera_->NextFrame(1000000).status, FrameStatus::kOk);
  FakeV4l2Device::FrameFault gap;
  gap.skip_sequence = 3;
  ASSERT_TRUE(fake_->ProduceFrame(gap));
  FrameResult r = camera_->NextFrame(1000000);
  ASSERT_EQ(r.status, FrameStatus::kOk);
  EXPECT_EQ(r.frame.info().frame_id, 4u);
  EXPECT_EQ(camera_->Stats().missing_frames, 3u);
}

TEST_F(V4l2CameraTest, BusyDeviceFailsStartWithMessage) {
  fake_->FailIoctl(VIDIOC_REQBUFS, EBUSY);
  ASSERT_TRUE(camera_->Configure(CameraConfig{}));
  Status s = camera_->Start();
  EXPECT_FALSE(s);
  EXPECT_NE(s.message.find("VIDIOC_REQBUFS: Device or resource busy"), std::string::npos)
      << s.message;
  EXPECT_TRUE(camera_->Start());  // the fault was transient
}

TEST_F(V4l2CameraTest, HeldFramesStarveTheDeviceUntilReleased) {
  StartMono8(/*buffers=*/2);
  std::vector<Frame> held;
  for (int i = 0; i < 2; ++i) {
    ASSERT_TRUE(fake_->ProduceFrame());
    FrameResult r = camera_->NextFrame(1000000);
    ASSERT_EQ(r.status, FrameStatus::kOk);
    held.push_back(std::move(r.frame));
  }
  EXPECT_FALSE(fake_->ProduceFrame());  // nothing queued: the device underruns
  EXPECT_EQ(fake_->underruns(), 1u);
  held.front().Reset();  // back to the driver: queued again
  EXPECT_EQ(fake_->queued_buffers(), 1);
  ASSERT_TRUE(fake_->ProduceFrame());
  FrameResult r = camera_->NextFrame(1000000);
  ASSERT_EQ(r.status, FrameStatus::kOk);
  EXPECT_EQ(r.frame.info().frame_id, 3u);
  EXPECT_EQ(camera_->Stats().missing_frames, 1u);  // the frame lost in the underrun
}

TEST_F(V4l2CameraTest, FramesOutliveStopAndUnmapOnRelease) {
  StartMono8();
  ASSERT_TRUE(fake_->ProduceFrame());
  FrameResult r = camera_->NextFrame(1000000);
  ASSERT_EQ(r.status, FrameStatus::kOk);
  camera_->Stop();
  EXPECT_EQ(fake_->mapped_buffers(), 4);  // still mapped for the held frame
  ExpectPattern(r.frame, 0);
  r.frame.Reset();
  EXPECT_EQ(fake_->mapped_buffers(), 0);
  ASSERT_TRUE(camera_->Start());  // restart after stop
  ASSERT_TRUE(fake_->ProduceFrame());
  EXPECT_EQ(camera_->NextFrame(1000000).status, FrameStatus::kOk);
}

TEST_F(V4l2CameraTest, UnplugWakesABlockedNextFrame) {
  StartMono8();
  std::thread unplug([&] { fake_->Unplug(); });
  FrameResult r = camera_->NextFrame(10'000'000);
  unplug.join();
  EXPECT_EQ(r.status, FrameStatus::kDisconnected) << r.message;
  EXPECT_EQ(camera_->NextFrame(1000).status, FrameStatus::kDisconnected);
  EXPECT_FALSE(camera_->Start());
}

}  // namespace
}  // namespace msmcal::camera

// Grabber + bounded queue + PNG writer, driven by the V4L2 driver on the fake device.
#include "acquisition/frames/frame_grabber.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <condition_variable>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "acquisition/frames/bounded_queue.h"
#include "drivers/camera/testing/fake_v4l2_device.h"
#include "drivers/camera/v4l2_camera.h"

namespace msmcal::frames {
namespace {

using camera::testing::FakeV4l2Device;

TEST(BoundedQueue, TryPushReportsFullAndCloseDrains) {
  BoundedQueue<int> q(2);
  int a = 1, b = 2, c = 3;
  EXPECT_TRUE(q.TryPush(a));
  EXPECT_TRUE(q.TryPush(b));
  EXPECT_FALSE(q.TryPush(c));
  q.Close();
  EXPECT_FALSE(q.TryPush(c));
  EXPECT_EQ(q.Pop(), 1);
  EXPECT_EQ(q.Pop(), 2);
  EXPECT_EQ(q.Pop(), std::nullopt);
}

class GrabberTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fake_ = std::make_shared<FakeV4l2Device>();
    fake_->SetAutoProduce(true);
    camera::V4l2CameraOptions options;
    options.syscalls = fake_;
    auto opened = camera::OpenV4l2Camera(options);
    ASSERT_TRUE(opened.camera) << opened.error;
    camera_ = std::move(opened.camera);
    camera::CameraConfig config;
    config.buffer_count = 6;
    ASSERT_TRUE(camera_->Configure(config));
    dir_ = std::filesystem::temp_directory_path() /
           ("msmcal_grab_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::shared_ptr<FakeV4l2Device> fake_;
  std::unique_ptr<camera::Camera> camera_;
  std::filesystem::path dir_;
};

TEST_F(GrabberTest, WritesEveryFrameAsPngWithItsExactContent) {
  PngWriterOptions writer_options;
  writer_options.dir = dir_;
  PngFolderWriter writer(writer_options);
  GrabberOptions options;
  options.max_frames = 12;
  options.writer_threads = 2;
  // The queue can hold more frames than the camera has buffers (6): TryPush never finds it full,
  // the camera waits for buffers instead, so nothing is dropped however slow the disk is.
  options.queue_capacity = 16;
  FrameGrabber grabber(*camera_, writer, options);
  ASSERT_TRUE(grabber.Start());
  grabber.Wait();
  grabber.Stop();
  const GrabberStats stats = grabber.Stats();
  EXPECT_EQ(stats.frames_grabbed, 12u);
  EXPECT_EQ(stats.frames_written, 12u);
  EXPECT_EQ(stats.frames_dropped, 0u);
  EXPECT_EQ(stats.write_errors, 0u);
  EXPECT_EQ(stats.camera.failed, 0u);
  EXPECT_GT(stats.bytes_written, 0u);
  for (uint64_t k = 0; k < 12; ++k) {
    const cv::Mat image = cv::imread(writer.PathFor(k).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(image.cols, 640);
    ASSERT_EQ(image.rows, 480);
    ASSERT_EQ(image.type(), CV_8UC1);
    const uint8_t* data = image.ptr<uint8_t>(0);
    uint64_t seq = 0;
    for (int i = 0; i < 8; ++i) seq |= static_cast<uint64_t>(data[i]) << (8 * i);
    EXPECT_EQ(seq, k);  // grab order = device order, no gaps
    for (size_t i = 0; i < 640u * 480u; i += 101) {
      ASSERT_EQ(data[i], FakeV4l2Device::PatternByte(seq, i)) << "frame " << k << " byte " << i;
    }
  }
  EXPECT_FALSE(std::filesystem::exists(writer.PathFor(12)));
}

// A sink that holds every write until released: the queue fills and the grabber must drop.
class GatedSink : public FrameSink {
 public:
  Result Write(const camera::Frame& frame, uint64_t) override {
    std::unique_lock<std::mutex> lock(mutex_);
    ++entered_;
    entered_cv_.notify_all();
    open_cv_.wait(lock, [&] { return open_; });
    return {true, frame.size_bytes(), ""};
  }
  void WaitEntered(int n) {
    std::unique_lock<std::mutex> lock(mutex_);
    entered_cv_.wait(lock, [&] { return entered_ >= n; });
  }
  void Open() {
    std::lock_guard<std::mutex> lock(mutex_);
    open_ = true;
    open_cv_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable entered_cv_, open_cv_;
  int entered_ = 0;
  bool open_ = false;
};

TEST_F(GrabberTest, CountsFramesDroppedWhenStorageFallsBehind) {
  GatedSink sink;
  GrabberOptions options;
  options.queue_capacity = 1;
  options.max_frames = 8;
  FrameGrabber grabber(*camera_, sink, options);
  ASSERT_TRUE(grabber.Start());
  sink.WaitEntered(1);  // writer busy with frame 0, queue holds at most 1 more
  // The capture loop never waits for storage: it ends after 8 frames while the writer is held.
  grabber.WaitForCaptureEnd();
  sink.Open();
  grabber.Wait();
  grabber.Stop();
  const GrabberStats stats = grabber.Stats();
  EXPECT_EQ(stats.frames_grabbed, 8u);
  EXPECT_GT(stats.frames_dropped, 0u);
  EXPECT_EQ(stats.frames_written + stats.frames_dropped, 8u);
}

// A camera that opened but streams nothing: with max_consecutive_timeouts the capture ends and
// says why instead of waiting for ever; frames that do come reset the count.
TEST_F(GrabberTest, EndsAfterConsecutiveTimeoutsAndSaysWhy) {
  fake_->SetAutoProduce(false);
  GatedSink sink;
  sink.Open();
  GrabberOptions options;
  options.max_frames = 5;
  options.frame_timeout_us = 1000;
  options.max_consecutive_timeouts = 3;
  FrameGrabber grabber(*camera_, sink, options);
  ASSERT_TRUE(grabber.Start());
  grabber.Wait();
  grabber.Stop();
  const GrabberStats stats = grabber.Stats();
  EXPECT_EQ(stats.frames_grabbed, 0u);
  EXPECT_EQ(stats.timeouts, 3u);
  EXPECT_NE(stats.last_error.find("no frame in 3 waits of 1 ms in a row"), std::string::npos)
      << stats.last_error;
}

TEST_F(GrabberTest, RatesFromInjectedClock) {
  GatedSink sink;
  sink.Open();
  std::atomic<int64_t> fake_now{0};
  GrabberOptions options;
  options.max_frames = 5;
  options.writer_threads = 1;
  options.queue_capacity = 16;                                      // no drops (see above)
  options.now_ns = [&] { return fake_now.fetch_add(50'000'000); };  // +50 ms per reading
  FrameGrabber grabber(*camera_, sink, options);
  ASSERT_TRUE(grabber.Start());
  grabber.Wait();
  grabber.Stop();
  const GrabberStats stats = grabber.Stats();
  EXPECT_EQ(stats.frames_written, 5u);
  // 10 clock readings (one per grab, one per write): first grab at 0, last write at most 450 ms.
  EXPECT_GE(stats.fps, 5 / 0.45 - 1e-9);
  EXPECT_NEAR(stats.mb_per_s, stats.fps * 640 * 480 / 1e6, 1e-9);
}

TEST(GrabberOptions, ValidateNamesField) {
  GrabberOptions options;
  options.writer_threads = 0;
  EXPECT_EQ(options.Validate(), "GrabberOptions.writer_threads = 0: must be in [1, 64]");
}

}  // namespace
}  // namespace msmcal::frames

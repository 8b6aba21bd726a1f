// The mock GigE Vision camera: its frame sources, and conformance with a client we did not write
// (Aravis's arv-camera-test-0.8 streams from it with zero failures and reports its geometry).
#include "mocks/camera/mock_gv_camera.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>

#include "drivers/camera/testing/subprocess.h"

namespace msmcal::sim {
namespace {

using camera::testing::ProgramInPath;
using camera::testing::Subprocess;

TEST(TestPatternSource, DeterministicWithIndexHeader) {
  FrameSource source = MakeTestPatternSource();
  std::vector<uint8_t> a(100 * 50 * 2), b(a.size());
  source(a.data(), 100, 50, SimPixelFormat::kMono16, 0, 42);
  source(b.data(), 100, 50, SimPixelFormat::kMono16, 999, 42);
  EXPECT_EQ(a, b);
  for (size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a[i], PatternByte(42, i)) << i;
  EXPECT_EQ(a[0], 42);
  source(b.data(), 100, 50, SimPixelFormat::kMono16, 0, 43);
  EXPECT_NE(a, b);
}

TEST(ReplaySource, ConvertsAndPlacesImagesInOrderThenLoops) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("msmcal_replay_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  cv::Mat first(4, 6, CV_8UC1, cv::Scalar(10));
  cv::Mat second(4, 6, CV_8UC3, cv::Scalar(0, 200, 0));  // BGR green
  ASSERT_TRUE(cv::imwrite((dir / "0001.png").string(), second));
  ASSERT_TRUE(cv::imwrite((dir / "0000.png").string(), first));
  FrameSource source = MakeReplaySource(ListPngFiles(dir));
  std::vector<uint8_t> frame(8 * 5 * 3, 0xAA);
  source(frame.data(), 8, 5, SimPixelFormat::kMono8, 0, 0);
  EXPECT_EQ(frame[0], 10);         // first file (sorted by name)
  EXPECT_EQ(frame[7], 0);          // right of the 6-pixel image: black
  EXPECT_EQ(frame[4 * 8 + 0], 0);  // below the 4-row image: black
  source(frame.data(), 8, 5, SimPixelFormat::kRGB8, 0, 1);
  EXPECT_EQ(frame[0], 0);                                     // R
  EXPECT_EQ(frame[1], 200);                                   // G
  source(frame.data(), 8, 5, SimPixelFormat::kMono16, 0, 2);  // loops to the first file
  EXPECT_EQ(frame[0] | (frame[1] << 8), 10 * 256);
  std::filesystem::remove_all(dir);
  EXPECT_THROW(ListPngFiles(dir), std::runtime_error);
}

TEST(MockGvCameraOptions, ValidateNamesField) {
  MockGvCameraOptions options;
  EXPECT_EQ(options.Validate(), "");
  options.frame_rate_hz = 0;
  EXPECT_NE(options.Validate().find("frame_rate_hz = 0"), std::string::npos);
}

// arv-camera-test-0.8 prints "image width = N", "payload = N bytes" and "n_failures = N".
int64_t ReportedValue(const std::string& output, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(output, m, std::regex(key + "\\s*=\\s*(\\d+)"))) return -1;
  return std::stoll(m[1]);
}

TEST(MockGvCamera, ArvCameraTestStreams10MegapixelFramesWithZeroFailures) {
  if (!ProgramInPath("arv-camera-test-0.8")) {
    GTEST_SKIP() << "arv-camera-test-0.8 not installed (Debian package aravis-tools)";
  }
  MockGvCameraOptions options;  // 3840 x 2748 Mono8
  options.frame_rate_hz = 5;
  std::string error;
  auto server = MockGvCamera::Start(options, MakeTestPatternSource(), &error);
  ASSERT_TRUE(server) << error;
  ASSERT_TRUE(server->Answers());
  Subprocess tool(
      {"arv-camera-test-0.8", "-n", "127.0.0.1", "-i", "8192", "-a", "--duration", "3"});
  std::string output;
  const int status = tool.WaitWithOutput(/*timeout_ms=*/30000, &output);
  ASSERT_EQ(status, 0) << output;
  EXPECT_EQ(ReportedValue(output, "image width"), 3840) << output;
  EXPECT_EQ(ReportedValue(output, "image height"), 2748) << output;
  // Mono8: 1 byte per pixel (payload = width * height * bytes per pixel).
  EXPECT_EQ(ReportedValue(output, "payload"), 3840 * 2748) << output;
  EXPECT_EQ(ReportedValue(output, "n_failures"), 0) << output;
  EXPECT_EQ(ReportedValue(output, "n_missing_packets"), 0) << output;
  EXPECT_GE(ReportedValue(output, "n_completed_buffers"), 5) << output;
  EXPECT_GE(server->frames_served(), 5u);
}

TEST(MockGvCamera, ServesACustomSensorSizeAndAnswers) {
  MockGvCameraOptions options;
  options.sensor_width = 64;
  options.sensor_height = 48;
  std::string error;
  auto server = MockGvCamera::Start(options, nullptr, &error);
  ASSERT_TRUE(server) << error;
  EXPECT_TRUE(server->Answers());
  EXPECT_EQ(server->options().sensor_width, 64);
}

}  // namespace
}  // namespace msmcal::sim

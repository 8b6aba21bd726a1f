// frames::FrameImage and the PNG writer: every pixel format becomes the interchange format's
// image (mono, or BGR), colour cameras included.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <vector>

#include "acquisition/frames/frame_writer.h"
#include "processing/vision/dots.h"
#include "tests/testing/bayer.h"

namespace msmcal::frames {
namespace {

camera::Frame FrameOf(const cv::Mat& pixels, camera::PixelFormat format) {
  camera::FrameInfo info;
  info.width = pixels.cols;
  info.height = pixels.rows;
  info.pixel_format = format;
  const cv::Mat contiguous = pixels.clone();
  return camera::Frame::Owned(info, std::vector<uint8_t>(contiguous.datastart, contiguous.dataend));
}

std::filesystem::path TestDir() {
  return std::filesystem::temp_directory_path() /
         ("msmcal_frame_image_" + std::to_string(::getpid()) + "_" +
          ::testing::UnitTest::GetInstance()->current_test_info()->name());
}

TEST(FrameImage, RgbBecomesBgrAndMonoIsAViewOfTheBuffer) {
  const cv::Mat rgb(4, 6, CV_8UC3, cv::Scalar(210, 120, 40));  // R, G, B in memory
  const cv::Mat bgr = FrameImage(FrameOf(rgb, camera::PixelFormat::kRGB8));
  ASSERT_EQ(bgr.type(), CV_8UC3);
  EXPECT_EQ(bgr.at<cv::Vec3b>(2, 3), cv::Vec3b(40, 120, 210));
  const camera::Frame mono =
      FrameOf(cv::Mat(4, 6, CV_8UC1, cv::Scalar(7)), camera::PixelFormat::kMono8);
  const cv::Mat view = FrameImage(mono);
  EXPECT_EQ(view.data, mono.data());
  EXPECT_EQ(view.type(), CV_8UC1);
}

// A Bayer camera's raw frame (GenICam BayerRG8: R G / G B from the first pixel) is written as
// the colour image it shows, not as a grey mosaic the solver would read as mono, and the solver
// can tell which half of its green was interpolated.
TEST(FrameImage, BayerRawIsWrittenDemosaicedInBgr) {
  const cv::Mat flat(8, 10, CV_8UC3, cv::Scalar(40, 120, 210));  // B, G, R
  const cv::Mat shown =
      FrameImage(FrameOf(msmcal::testing::BayerMosaic(flat, /*interpolated_parity=*/0),
                         camera::PixelFormat::kBayerRG8));
  ASSERT_EQ(shown.type(), CV_8UC3);
  EXPECT_EQ(shown.at<cv::Vec3b>(4, 5), cv::Vec3b(40, 120, 210));

  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(128, 6);
  cv::Mat scene(120, 160, CV_8UC3);
  for (auto it = scene.begin<cv::Vec3b>(); it != scene.end<cv::Vec3b>(); ++it)
    for (int c = 0; c < 3; ++c) (*it)[c] = cv::saturate_cast<uint8_t>(noise(rng));
  const std::filesystem::path dir = TestDir();
  std::filesystem::remove_all(dir);
  PngWriterOptions options;
  options.dir = dir;
  PngFolderWriter writer(options);
  ASSERT_TRUE(
      writer
          .Write(FrameOf(msmcal::testing::BayerMosaic(scene, 0), camera::PixelFormat::kBayerRG8), 0)
          .ok);
  const cv::Mat read = cv::imread(writer.PathFor(0).string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(read.type(), CV_8UC3);
  EXPECT_EQ(vision::InterpolatedGreenParity(read), 0);
  EXPECT_EQ(vision::InterpolatedGreenParity(scene), -1);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace msmcal::frames

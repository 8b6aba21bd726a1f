// Colour cameras whose BGR comes from a Bayer mosaic (vision/dots.h, InterpolatedGreenParity):
// the interpolated half of the green channel is recognised from the data, and saturated green
// spots are fitted to the measured half.
#include "tests/testing/bayer.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "processing/vision/dots.h"

namespace msmcal::vision {
namespace {

using msmcal::testing::BayerMosaic;
using msmcal::testing::Demosaic;

// Adds a Gaussian spot (peak in full scales) to a float image.
void AddSpot(cv::Mat1f& img, double u, double v, double sigma, double peak) {
  const int r = static_cast<int>(std::ceil(5 * sigma));
  for (int y = std::max(0, static_cast<int>(v) - r);
       y <= std::min(img.rows - 1, static_cast<int>(v) + r); ++y)
    for (int x = std::max(0, static_cast<int>(u) - r);
         x <= std::min(img.cols - 1, static_cast<int>(u) + r); ++x)
      img(y, x) += static_cast<float>(
          peak * std::exp(-((x - u) * (x - u) + (y - v) * (y - v)) / (2 * sigma * sigma)));
}

// A light screen with noise and saturated green spots (a green laser: the green channel only)
// as a sensor with three measured channels sees it; `truth` gets the spots' centres.
cv::Mat ScreenWithGreenSpots(int depth, uint64_t seed, std::vector<Eigen::Vector2d>* truth) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> noise(0, 0.004);
  cv::Mat1f b(240, 320, 0.55f), g(240, 320, 0.6f), r(240, 320, 0.58f);
  for (int k = 0; k < 12; ++k) {
    const double x = 20 + (k % 4) * 80 + 20 * u(rng), y = 25 + (k / 4) * 75 + 20 * u(rng);
    AddSpot(g, x, y, 1.3, 2.0);
    truth->emplace_back(x, y);
  }
  std::vector<cv::Mat> channels;
  for (cv::Mat1f* c : {&b, &g, &r}) {
    for (auto& v : *c) v = std::clamp(v + static_cast<float>(noise(rng)), 0.0f, 1.0f);
    cv::Mat out;
    c->convertTo(out, depth, depth == CV_16U ? 65535.0 : 255.0);
    channels.push_back(out);
  }
  cv::Mat bgr;
  cv::merge(channels, bgr);
  return bgr;
}

double RmsError(const std::vector<Dot>& dots, const std::vector<Eigen::Vector2d>& truth) {
  double s2 = 0;
  for (const auto& t : truth) {
    double best = 1e9;
    for (const auto& d : dots) best = std::min(best, (d.px - t).norm());
    s2 += best * best;
  }
  return std::sqrt(s2 / static_cast<double>(truth.size()));
}

TEST(BayerTest, TheMosaicAndOpenCvsCodesAgreeOnAFlatColour) {
  const cv::Mat flat(8, 8, CV_8UC3, cv::Scalar(40, 120, 210));
  for (int parity : {0, 1})
    for (int how : {0, 1}) {
      cv::Mat back;
      back = Demosaic(BayerMosaic(flat, parity), parity, how == 1);
      EXPECT_EQ(back.at<cv::Vec3b>(4, 4), cv::Vec3b(40, 120, 210)) << parity << " " << how;
    }
}

TEST(BayerTest, InterpolatedGreenIsReadFromTheImage) {
  std::vector<Eigen::Vector2d> truth;
  const cv::Mat measured = ScreenWithGreenSpots(CV_8U, 5, &truth);
  EXPECT_EQ(InterpolatedGreenParity(measured), -1);
  cv::Mat mono;
  cv::cvtColor(measured, mono, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(InterpolatedGreenParity(mono), -1);
  EXPECT_EQ(InterpolatedGreenParity(cv::Mat(64, 64, CV_8UC3, cv::Scalar(9, 99, 199))), -1);
  for (int depth : {CV_8U, CV_16U})
    for (int parity : {0, 1})
      for (int how : {0, 1}) {
        truth.clear();
        const cv::Mat demosaiced =
            Demosaic(BayerMosaic(ScreenWithGreenSpots(depth, 7, &truth), parity), parity, how == 1);
        EXPECT_EQ(InterpolatedGreenParity(demosaiced), parity)
            << "depth " << depth << " parity " << parity << " how " << how;
      }
}

// Saturated green spots (sigma 1.3 px, peak twice full scale) through a Bayer mosaic: fitted
// over every pixel, the interpolated half (which mixes clipped and unclipped neighbours) moves
// them; fitted over the measured half they are where a three-channel sensor puts them.
TEST(BayerTest, SpotsAreFittedToTheMeasuredGreens) {
  for (int how : {0, 1}) {
    std::vector<Eigen::Vector2d> truth;
    const cv::Mat measured = ScreenWithGreenSpots(CV_8U, 11, &truth);
    const cv::Mat demosaiced = Demosaic(BayerMosaic(measured, 0), 0, how == 1);
    DotOptions all_pixels;
    all_pixels.native_green_only = false;
    const std::vector<Dot> on = DetectDots(demosaiced, DotOptions{});
    const std::vector<Dot> off = DetectDots(demosaiced, all_pixels);
    const std::vector<Dot> three = DetectDots(measured, DotOptions{});
    ASSERT_EQ(on.size(), truth.size());
    ASSERT_EQ(off.size(), truth.size());
    const double rms_on = RmsError(on, truth), rms_off = RmsError(off, truth);
    std::printf(
        "demosaic %d: dots %.4f px RMS (measured greens), %.4f px (every pixel); three "
        "measured channels %.4f px\n",
        how, rms_on, rms_off, RmsError(three, truth));
    EXPECT_LT(rms_on, 0.05);
    EXPECT_LT(rms_on, 0.6 * rms_off);
  }
}

}  // namespace
}  // namespace msmcal::vision

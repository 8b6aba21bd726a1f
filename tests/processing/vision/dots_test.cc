#include "processing/vision/dots.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

namespace msmcal::vision {
namespace {

// Adds a Gaussian spot (peak in [0, 1] of full scale) to a float image.
void AddSpot(cv::Mat1f& img, double u, double v, double sigma, double peak) {
  const int r = static_cast<int>(std::ceil(5 * sigma));
  for (int y = std::max(0, static_cast<int>(v) - r);
       y <= std::min(img.rows - 1, static_cast<int>(v) + r); ++y)
    for (int x = std::max(0, static_cast<int>(u) - r);
         x <= std::min(img.cols - 1, static_cast<int>(u) + r); ++x)
      img(y, x) += static_cast<float>(
          peak * std::exp(-((x - u) * (x - u) + (y - v) * (y - v)) / (2 * sigma * sigma)));
}

cv::Mat ToType(const cv::Mat1f& f, int depth) {
  cv::Mat out;
  f.convertTo(out, depth, depth == CV_16U ? 65535.0 : 255.0);
  return out;
}

struct Truth {
  double u, v;
};

std::vector<Truth> Spots() {
  return {{100.3, 80.7}, {250.55, 60.2}, {40.9, 190.45}, {300.1, 200.8}};
}

TEST(DetectDotsTest, CentroidsOnDarkBackgroundMono8And16) {
  for (int depth : {CV_8U, CV_16U}) {
    cv::Mat1f f(240, 360, 0.05f);
    for (const auto& s : Spots()) AddSpot(f, s.u, s.v, 1.6, 0.7);
    const auto dots = DetectDots(ToType(f, depth));
    ASSERT_EQ(dots.size(), Spots().size());
    for (const auto& s : Spots()) {
      double best = 1e9;
      for (const auto& d : dots) best = std::min(best, std::hypot(d.px.x() - s.u, d.px.y() - s.v));
      // Truncation at the threshold biases by up to ~0.1 px at this SNR.
      EXPECT_LT(best, 0.12) << "spot at " << s.u << ", " << s.v;
    }
    for (const auto& d : dots) {
      EXPECT_GT(d.cov_px2(0, 0), 0);
      EXPECT_GT(d.cov_px2.determinant(), 0);
    }
  }
}

TEST(DetectDotsTest, GreenDotsInColourIgnoreWhiteSquares) {
  cv::Mat1f g(240, 360, 0.05f);
  for (const auto& s : Spots()) AddSpot(g, s.u, s.v, 1.6, 0.7);
  cv::Mat1f grey(240, 360, 0.05f);
  grey(cv::Rect(150, 100, 60, 60)) = 0.8f;  // a white square: equal in B, G, R
  cv::Mat1f green = g + grey - 0.05f;
  std::vector<cv::Mat> ch = {ToType(grey, CV_8U), ToType(green, CV_8U), ToType(grey, CV_8U)};
  cv::Mat bgr;
  cv::merge(ch, bgr);
  const auto dots = DetectDots(bgr);
  EXPECT_EQ(dots.size(), Spots().size());
}

TEST(DetectDotsTest, DotOnLightSquareFoundThroughTopHat) {
  cv::Mat1f f(120, 120, 0.06f);
  f(cv::Rect(30, 30, 50, 50)) = 0.8f;  // light square
  AddSpot(f, 55.4, 52.6, 1.6, 0.3);
  const auto dots = DetectDots(ToType(f, CV_8U));
  ASSERT_EQ(dots.size(), 1u);
  EXPECT_NEAR(dots[0].px.x(), 55.4, 0.1);
  EXPECT_NEAR(dots[0].px.y(), 52.6, 0.1);
}

TEST(DetectDotsTest, LeavesTheCallersImageUntouched) {
  // Regression: the top-hat used to be written into the caller's buffer (a shared cv::Mat),
  // darkening frames the orchestrator then saved.
  cv::Mat1f f(120, 120, 0.06f);
  f(cv::Rect(30, 30, 50, 50)) = 0.8f;
  AddSpot(f, 55.4, 52.6, 1.6, 0.3);
  const cv::Mat image = ToType(f, CV_8U);
  const cv::Mat before = image.clone();
  ASSERT_EQ(DetectDots(image).size(), 1u);
  EXPECT_EQ(cv::norm(image, before, cv::NORM_INF), 0.0);
}

TEST(DetectDotsTest, RejectsSmallLargeAndElongatedBlobs) {
  cv::Mat1f f(200, 200, 0.0f);
  f(10, 10) = 1.0f;                                        // single hot pixel: too small
  cv::line(f, {50, 150}, {120, 160}, cv::Scalar(0.9), 3);  // a streak: elongated
  DotOptions o;
  o.background_kernel_px = 0;
  o.max_pixels = 100;
  f(cv::Rect(100, 20, 30, 30)) = 0.9f;  // 900 px: too large
  DotRejections rej;
  const auto dots = DetectDots(ToType(f, CV_8U), o, &rej);
  EXPECT_TRUE(dots.empty());
  EXPECT_GE(rej.too_small, 1);
  EXPECT_GE(rej.too_large + rej.elongated, 2);
}

// The covariance model (scatter / N_eff): on repeated noisy renderings the centroid scatter is
// of the order of the reported sigma (it is an upper-bound style model; see docs/solver.md).
TEST(DetectDotsTest, CovarianceIsPositiveAndScalesWithSpotSize) {
  cv::Mat1f small(60, 60, 0.0f), large(60, 60, 0.0f);
  AddSpot(small, 30.2, 29.7, 1.2, 0.7);
  AddSpot(large, 30.2, 29.7, 2.4, 0.7);
  const auto a = DetectDots(ToType(small, CV_8U));
  const auto b = DetectDots(ToType(large, CV_8U));
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_GT(b[0].num_pixels, a[0].num_pixels);
}

TEST(DotOptionsTest, ValidateNamesTheField) {
  DotOptions o;
  EXPECT_EQ(o.Validate(), "");
  o.background_kernel_px = 10;
  EXPECT_NE(o.Validate().find("background_kernel_px = 10"), std::string::npos);
  EXPECT_THROW(DetectDots(cv::Mat1b(10, 10), o), std::invalid_argument);
}

}  // namespace
}  // namespace msmcal::vision

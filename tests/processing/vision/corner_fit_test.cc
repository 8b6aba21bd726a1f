// vision::FitCorner against corners rendered with a known centre: edges that are not at right
// angles (a slanted board), pixel integration, Gaussian blur, sensor noise, a gamma curve, uneven
// light. Its centre is unbiased, scatters less than cornerSubPix on the same pixels, and its
// covariance matches its scatter.

#include "processing/vision/corner_fit.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

namespace msmcal::vision {
namespace {

struct Scene {
  Eigen::Vector2d centre{20.3, 19.7};
  double theta1_deg = 8, theta2_deg = 71;  // directions of the two edge lines
  double blur_sigma = 1.0;
  double dark = 40, light = 200;  // levels (8-bit units)
  double noise = 2.0;
  double gamma = 1.0;
  double gradient = 0;  // levels per px along x (uneven light, multiplies the reflectance)
};

Eigen::Vector2d Dir(double deg) {
  const double a = deg * M_PI / 180;
  return {std::cos(a), std::sin(a)};
}

cv::Mat Render(const Scene& s, std::mt19937& rng) {
  constexpr int kSize = 41, kSuper = 8;
  const Eigen::Vector2d d1 = Dir(s.theta1_deg), d2 = Dir(s.theta2_deg);
  const Eigen::Vector2d n1(-d1.y(), d1.x()), n2(-d2.y(), d2.x());
  cv::Mat img(kSize, kSize, CV_32F);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      double acc = 0;
      for (int j = 0; j < kSuper; ++j)
        for (int i = 0; i < kSuper; ++i) {
          const Eigen::Vector2d p(x - 0.5 + (i + 0.5) / kSuper, y - 0.5 + (j + 0.5) / kSuper);
          const Eigen::Vector2d q = p - s.centre;
          acc += (n1.dot(q) > 0) == (n2.dot(q) > 0) ? 1.0 : 0.0;
        }
      img.at<float>(y, x) = static_cast<float>(acc / (kSuper * kSuper));
    }
  cv::GaussianBlur(img, img, cv::Size(0, 0), s.blur_sigma);
  std::normal_distribution<double> noise(0, s.noise);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      const double refl = std::pow(img.at<float>(y, x), s.gamma);
      const double light = 1.0 + s.gradient * (x - s.centre.x()) / s.light;
      img.at<float>(y, x) =
          static_cast<float>((s.dark + (s.light - s.dark) * refl) * light + noise(rng));
    }
  return img;
}

struct Stats {
  Eigen::Vector2d mean_fit = Eigen::Vector2d::Zero(), mean_subpix = Eigen::Vector2d::Zero();
  double rms_fit = 0, rms_subpix = 0, mean_nees = 0;  // nees: e^T cov^-1 e / 2
  int failed = 0;
};

Stats RunTrials(const Scene& s, int trials, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.5, 0.5);
  Stats st;
  int n = 0;
  for (int t = 0; t < trials; ++t) {
    Scene sc = s;
    sc.centre += Eigen::Vector2d(jitter(rng), jitter(rng));
    const cv::Mat img = Render(sc, rng);
    // cornerSubPix from a start 0.7 px off, as a detector's grid would give.
    std::vector<cv::Point2f> pt = {cv::Point2f(static_cast<float>(sc.centre.x() + 0.5),
                                               static_cast<float>(sc.centre.y() - 0.5))};
    cv::cornerSubPix(img, pt, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 40, 1e-3));
    const Eigen::Vector2d sub(pt[0].x, pt[0].y);
    const auto f = FitCorner(img, sub, 12 * Dir(sc.theta1_deg), 18 * Dir(sc.theta2_deg), 5.0);
    if (!f) {
      ++st.failed;
      continue;
    }
    const Eigen::Vector2d e = f->px - sc.centre, es = sub - sc.centre;
    st.mean_fit += e, st.mean_subpix += es;
    st.rms_fit += e.squaredNorm(), st.rms_subpix += es.squaredNorm();
    st.mean_nees += 0.5 * e.dot(f->cov_px2.inverse() * e);
    ++n;
  }
  st.mean_fit /= n, st.mean_subpix /= n;
  st.rms_fit = std::sqrt(st.rms_fit / n), st.rms_subpix = std::sqrt(st.rms_subpix / n);
  st.mean_nees /= n;
  std::printf(
      "fit: RMS %.4f px, mean (%.4f %.4f), nees %.2f; cornerSubPix: RMS %.4f px, "
      "mean (%.4f %.4f); failed %d\n",
      st.rms_fit, st.mean_fit.x(), st.mean_fit.y(), st.mean_nees, st.rms_subpix, st.mean_subpix.x(),
      st.mean_subpix.y(), st.failed);
  return st;
}

// 300 trials: the mean of an unbiased fit is within ~3 sigma / sqrt(300) = 0.17 sigma of zero.
// The covariance is within about half its size of the scatter (the residual variance carries the
// model's mismatch: pixel integration, another PSF, a gamma); the solver rescales the corners'
// covariance by its variance components anyway.
void ExpectUnbiasedHonestAndBetter(const Stats& st) {
  EXPECT_EQ(st.failed, 0);
  EXPECT_LT(st.mean_fit.norm(), 0.25 * st.rms_fit + 0.002);
  EXPECT_LT(st.rms_fit, 0.8 * st.rms_subpix);
  EXPECT_GT(st.mean_nees, 0.6);
  EXPECT_LT(st.mean_nees, 1.6);
}

TEST(CornerFitTest, SlantedCornerUnderNoiseIsUnbiasedHonestAndTighterThanCornerSubPix) {
  ExpectUnbiasedHonestAndBetter(RunTrials(Scene{}, 300, 1));
}

TEST(CornerFitTest, GammaAndWideBlurDoNotBiasIt) {
  Scene s;
  s.gamma = 0.6;
  s.blur_sigma = 1.6;
  ExpectUnbiasedHonestAndBetter(RunTrials(s, 300, 2));
}

TEST(CornerFitTest, UnevenLightDoesNotBiasIt) {
  Scene s;
  s.gradient = 3.0;  // 3 levels per px: the light varies by +-7 % across the window
  ExpectUnbiasedHonestAndBetter(RunTrials(s, 300, 5));
}

TEST(CornerFitTest, NearlyOrthogonalSharpCorner) {
  Scene s;
  s.theta1_deg = -3, s.theta2_deg = 88;
  s.blur_sigma = 0.6;
  s.noise = 4;
  ExpectUnbiasedHonestAndBetter(RunTrials(s, 300, 3));
}

TEST(CornerFitTest, RefusesWhatIsNotACorner) {
  cv::Mat flat(41, 41, CV_32F, cv::Scalar(120));
  EXPECT_FALSE(FitCorner(flat, {20, 20}, {10, 0}, {0, 10}, 5.0));
  // Window leaving the image, a wrong type, a degenerate direction.
  std::mt19937 rng(4);
  const cv::Mat img = Render(Scene{}, rng);
  EXPECT_FALSE(FitCorner(img, {2, 20}, {10, 0}, {0, 10}, 5.0));
  cv::Mat as8;
  img.convertTo(as8, CV_8U);
  EXPECT_FALSE(FitCorner(as8, {20, 20}, {10, 0}, {0, 10}, 5.0));
  EXPECT_FALSE(FitCorner(img, {20, 20}, {0, 0}, {0, 10}, 5.0));
}

}  // namespace
}  // namespace msmcal::vision

#include "processing/vision/dots.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>

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

double NearestError(const std::vector<Dot>& dots, double u, double v, const Dot** which = nullptr) {
  double best = 1e9;
  for (const auto& d : dots) {
    const double e = std::hypot(d.px.x() - u, d.px.y() - v);
    if (e < best) {
      best = e;
      if (which) *which = &d;
    }
  }
  return best;
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

// BGR: a green spot on a light square saturates green while blue and red still rise (the
// simulator's spot weights): it is found through the green channel's top-hat and fitted by its
// flanks; a small white speck of the same size is not green and is rejected.
TEST(DetectDotsTest, GreenSpotSaturatedOnLightSquareAndWhiteSpeck) {
  cv::Mat1f spot(160, 160, 0.0f);
  AddSpot(spot, 60.3, 70.6, 1.7, 0.7);
  cv::Mat1f grey(160, 160, 0.06f);
  grey(cv::Rect(30, 30, 70, 80)) = 0.8f;   // light square under the spot
  grey(cv::Rect(120, 120, 5, 5)) = 0.95f;  // white speck, dot-sized
  const double weight[3] = {0.20, 1.0, 0.12};
  std::vector<cv::Mat> ch;
  for (int c = 0; c < 3; ++c) {
    cv::Mat1f level = grey + spot * weight[c];
    cv::min(level, 1.0f, level);
    ch.push_back(ToType(level, CV_8U));
  }
  cv::Mat bgr;
  cv::merge(ch, bgr);
  DotRejections rej;
  const auto dots = DetectDots(bgr, {}, &rej);
  ASSERT_EQ(dots.size(), 1u);
  EXPECT_EQ(rej.not_green, 1);
  EXPECT_GT(dots[0].saturated_pixels, 0);
  EXPECT_TRUE(dots[0].fitted);
  EXPECT_LT(NearestError(dots, 60.3, 70.6), 0.03);
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

// ---- The Gaussian fit (DotCentre::kGaussianFit) ----

// Noiseless spots: the centroid is biased by the threshold cut at pixel boundaries, the fit is
// not (Mono16: no quantisation to speak of).
TEST(DotFitTest, UnbiasedWhereTheCentroidIsNot) {
  cv::Mat1f f(240, 360, 0.05f);
  for (const auto& s : Spots()) AddSpot(f, s.u, s.v, 1.6, 0.7);
  DotOptions centroid;
  centroid.centre = DotCentre::kWeightedCentroid;
  const cv::Mat img = ToType(f, CV_16U);
  const auto fitted = DetectDots(img);
  const auto plain = DetectDots(img, centroid);
  double worst_fit = 0, worst_centroid = 0;
  for (const auto& s : Spots()) {
    worst_fit = std::max(worst_fit, NearestError(fitted, s.u, s.v));
    worst_centroid = std::max(worst_centroid, NearestError(plain, s.u, s.v));
  }
  EXPECT_LT(worst_fit, 0.002);
  EXPECT_GT(worst_centroid, 0.01);
  for (const auto& d : fitted) EXPECT_TRUE(d.fitted);
}

// A spot clipped at full scale (peak 2x full scale) on a dark background: its saturated core
// only bounds the model, the flanks place it.
TEST(DotFitTest, SaturatedSpotIsPlacedByItsFlanks) {
  cv::Mat1f f(120, 120, 0.05f);
  AddSpot(f, 60.37, 58.81, 1.8, 2.0);
  cv::min(f, 1.0f, f);
  DotOptions o;
  o.max_saturated_fraction = 1.0;
  const auto dots = DetectDots(ToType(f, CV_16U), o);
  ASSERT_EQ(dots.size(), 1u);
  EXPECT_GT(dots[0].saturated_pixels, 5);
  EXPECT_TRUE(dots[0].fitted);
  EXPECT_LT(NearestError(dots, 60.37, 58.81), 0.005);
}

// JPEG (quality 85) ripples a clipped spot's flat top by several percent: the rippled pixels
// are clipped, not measurements (DotOptions::plateau_tolerance_fraction). Mono 8-bit, sigma
// 1.3 px spots at twice full scale on a plain background, at sub-pixel positions.
TEST(DotFitTest, JpegRippledSaturatedSpotIsPlacedByItsFlanks) {
  cv::Mat1f f(160, 400, 0.25f);
  std::vector<Truth> truth;
  for (int k = 0; k < 12; ++k) {
    const Truth t{20.0 + 30 * k + 0.13 * k, 40.0 + 0.37 * k + (k % 3) * 35};
    truth.push_back(t);
    AddSpot(f, t.u, t.v, 1.3, 2.0);
  }
  cv::min(f, 1.0f, f);
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", ToType(f, CV_8U), jpeg, {cv::IMWRITE_JPEG_QUALITY, 85});
  const cv::Mat img = cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE);
  auto rms = [&](const DotOptions& o) {
    const auto dots = DetectDots(img, o);
    double s2 = 0;
    for (const auto& t : truth) s2 += std::pow(NearestError(dots, t.u, t.v), 2);
    return std::sqrt(s2 / truth.size());
  };
  DotOptions clean_only;  // flat tops within 1 % of their maximum only
  clean_only.plateau_tolerance_fraction = 0;
  const double now = rms(DotOptions{}), before = rms(clean_only);
  std::printf("JPEG 85, clipped spots: RMS %.4f px (ripple clipped), %.4f px (1 %% only)\n", now,
              before);
  EXPECT_LT(now, 0.08);
  EXPECT_LT(now, 0.7 * before);
}

// On repeated noisy renderings of one spot the fit's predicted sigma matches its scatter.
TEST(DotFitTest, CovarianceMatchesTheScatterOverNoise) {
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  double e2 = 0, v2 = 0;
  int n = 0;
  for (int k = 0; k < 200; ++k) {
    cv::Mat1f f(64, 64, 0.05f);
    AddSpot(f, 31.3, 32.6, 1.7, 0.6);
    for (auto& p : f) p += noise(rng);
    const auto dots = DetectDots(ToType(f, CV_16U));
    ASSERT_EQ(dots.size(), 1u);
    e2 += (dots[0].px - Eigen::Vector2d(31.3, 32.6)).squaredNorm();
    v2 += dots[0].cov_px2.trace();
    ++n;
  }
  const double ratio = std::sqrt(e2 / v2);
  std::printf("RMS error / RMS predicted sigma: %.3f\n", ratio);
  EXPECT_GT(ratio, 0.8);
  EXPECT_LT(ratio, 1.25);
}

// A spot at a square corner (X-junction), clipped on the light squares: over the top-hat
// background the fit is off (the opening does not reproduce the junction); over the background
// measured in two other images (the same squares, spots elsewhere) it is right. Where no other
// image sees the window dot-free, the dot is left alone.
TEST(DotFitTest, BackgroundFromOtherImagesRemovesASquareCorner) {
  auto scene = [](double u, double v) {
    cv::Mat1f f(120, 160, 0.06f);
    f(cv::Rect(80, 0, 80, 60)) = 0.8f;  // light squares: top right, bottom left
    f(cv::Rect(0, 60, 80, 60)) = 0.8f;
    cv::GaussianBlur(f, f, cv::Size(0, 0), 0.8);
    if (u > 0) AddSpot(f, u, v, 1.7, 0.7);
    cv::min(f, 1.0f, f);
    return ToType(f, CV_8U);
  };
  const double u = 78.6, v = 61.2;  // at the corner
  const cv::Mat own = scene(u, v);
  const std::vector<cv::Mat> others = {scene(30.2, 30.7), scene(120.4, 90.1)};
  auto dots = DetectDots(own);
  ASSERT_EQ(dots.size(), 1u);
  const double tophat_error = NearestError(dots, u, v);
  const cv::Rect window = DotFitWindow(dots[0], own.size(), DotOptions{});
  BackgroundPatch bg;
  for (const auto& img : others) {
    const auto img_dots = DetectDots(img);
    ASSERT_EQ(img_dots.size(), 1u);
    bg.Add(BackgroundContribution(img, img_dots, {window})[0]);
  }
  Dot refined = dots[0];
  ASSERT_TRUE(RefineDotOnBackground(ReadDotSignal(own, window), bg, DotOptions{}, &refined));
  EXPECT_TRUE(refined.on_background);
  const double refined_error = std::hypot(refined.px.x() - u, refined.px.y() - v);
  std::printf("corner spot: top-hat fit error %.4f px, fit over measured background %.4f px\n",
              tophat_error, refined_error);
  EXPECT_LT(refined_error, 0.02);
  EXPECT_GT(tophat_error, 0.025);  // measured 0.033
  EXPECT_GT(tophat_error, 5 * refined_error);
  // The only other image has its own spot at the same place: no dot-free view.
  BackgroundPatch blind = BackgroundContribution(own, dots, {window})[0];
  Dot untouched = dots[0];
  EXPECT_FALSE(RefineDotOnBackground(ReadDotSignal(own, window), blind, DotOptions{}, &untouched));
  EXPECT_EQ(untouched.px, dots[0].px);
  EXPECT_FALSE(untouched.on_background);
}

// A checkerboard of small tinted squares (light: lavender, green lowest), blurred, with a spot
// at an X-junction: the top-hat splits it into junction residue; over the scene without the
// spot the board cancels and the spot is one round blob, centred and green.
cv::Mat TintedBoard(double spot_u, double spot_v, double peak, int depth, double sigma = 1.5) {
  std::vector<cv::Mat1f> ch(3, cv::Mat1f(140, 140, 0.05f));
  const float light[3] = {0.78f, 0.62f, 0.74f};  // B, G, R
  for (int c = 0; c < 3; ++c) {
    ch[c] = cv::Mat1f(140, 140, 0.05f);
    for (int y = 0; y < 140; ++y)
      for (int x = 0; x < 140; ++x)
        if (((x / 14) + (y / 14)) % 2 == 0) ch[c](y, x) = light[c];
    cv::GaussianBlur(ch[c], ch[c], cv::Size(0, 0), 0.9);
  }
  const double weight[3] = {0.15, 1.0, 0.1};
  if (peak > 0)
    for (int c = 0; c < 3; ++c) AddSpot(ch[c], spot_u, spot_v, sigma, peak * weight[c]);
  std::vector<cv::Mat> out;
  for (auto& c : ch) {
    cv::min(c, 1.0f, c);
    out.push_back(ToType(c, depth));
  }
  cv::Mat bgr;
  cv::merge(out, bgr);
  return bgr;
}

TEST(DetectDotsOverBackgroundTest, SpotOnATintedSquareCornerIsOneRoundGreenBlob) {
  const double u = 70.2, v = 69.7;  // the junction of four squares at (70, 70)
  for (int depth : {CV_8U, CV_16U}) {
    const cv::Mat own = TintedBoard(u, v, 0.5, depth, /*sigma=*/2.6);
    const cv::Mat background = TintedBoard(0, 0, 0, depth);
    DotRejections rej;
    const auto dots = DetectDotsOverBackground(own, background, DotOptions{}, &rej);
    ASSERT_EQ(dots.size(), 1u) << "depth " << depth;
    EXPECT_TRUE(dots[0].fitted);
    EXPECT_LT(NearestError(dots, u, v), 0.01);
    EXPECT_EQ(rej.not_green, 0);
  }
}

// A crop of a rendered step 1 frame (randomised scene 8: BGR, tilt 24 deg, blur 0.9 px, squares
// 27 px) and of the same pose with the beams blocked: the spot sits on a square corner of a
// tinted board, where the default top-hat and the data-driven one leave corner residue (small
// or elongated blobs) with the spot's light in them, or the spot's clipped core alone; over the
// blocked frame it is one round blob.
TEST(DetectDotsOverBackgroundTest, RenderedSpotOnASquareCorner) {
  const std::string dir = std::string(MSMCAL_TEST_SOURCE_DIR) + "/tests/processing/vision/data/";
  const cv::Mat own = cv::imread(dir + "junction_spot.png", cv::IMREAD_UNCHANGED);
  const cv::Mat background = cv::imread(dir + "junction_spot_background.png", cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(own.empty() || background.empty());
  const Eigen::Vector2d where(48, 48);  // by eye, +-3 px
  auto near = [&](const std::vector<Dot>& dots) {
    return std::count_if(dots.begin(), dots.end(),
                         [&](const Dot& d) { return (d.px - where).norm() < 4; });
  };
  // The default top-hat keeps at most the spot's clipped core there (its saturated pixels count
  // down to half the threshold), never corner residue beside it.
  EXPECT_LE(near(DetectDots(own)), 1) << "default top-hat";
  const DotOptions adaptive = AdaptiveDotOptions(own, 26.7, DotOptions{});
  EXPECT_EQ(near(DetectDots(own, adaptive)), 0) << "adaptive top-hat";
  const auto dots = DetectDotsOverBackground(own, background, adaptive);
  ASSERT_EQ(dots.size(), 1u);
  EXPECT_EQ(near(dots), 1);
  EXPECT_TRUE(dots[0].fitted);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> shape(dots[0].scatter_px2);
  EXPECT_LT(std::sqrt(shape.eigenvalues()(1) / shape.eigenvalues()(0)), 1.5);  // round
}

TEST(DetectDotsOverBackgroundTest, SaturationIsReadFromTheImageAndWhiteLightIsRefused) {
  // A saturated spot on a light square: clipped pixels counted from the image itself.
  const cv::Mat background = TintedBoard(0, 0, 0, CV_8U);
  const cv::Mat own = TintedBoard(35.3, 35.6, 2.5, CV_8U);
  const auto dots = DetectDotsOverBackground(own, background, DotOptions{});
  ASSERT_EQ(dots.size(), 1u);
  EXPECT_GT(dots[0].saturated_pixels, 0);
  EXPECT_LT(NearestError(dots, 35.3, 35.6), 0.1);
  // White light (every channel rises alike) is not a laser spot.
  cv::Mat white = background.clone();
  cv::Mat speck(white.size(), white.type(), cv::Scalar::all(0));
  cv::circle(speck, cv::Point(100, 100), 3, cv::Scalar(40, 40, 40), cv::FILLED);
  white += speck;
  DotRejections rej;
  EXPECT_TRUE(DetectDotsOverBackground(white, background, DotOptions{}, &rej).empty());
  EXPECT_EQ(rej.not_green, 1);
  // A background of another size or type is refused.
  EXPECT_THROW(DetectDotsOverBackground(own, cv::Mat(10, 10, CV_8UC3), DotOptions{}),
               std::invalid_argument);
}

// A board exposed close to clipping (light squares at 0.91 of full scale, green-tinted: a
// colour balance): a laser spot on a light square clips there and shows only the square's
// headroom (0.09 of full scale, below the 0.15 threshold) as a saturated plateau, and raises red
// more than that. The spot is found, placed by its flanks, and nothing of the board is taken
// for a spot: first pass (top-hat) and over a spot-free view of the same scene.
cv::Mat NearlyClippedBoard(double spot_u, double spot_v, double peak, bool colour) {
  const float light[3] = {0.66f, 0.91f, 0.70f};  // B, G, R (mono: G)
  const double weight[3] = {0.2, 1.0, 0.35};
  std::vector<cv::Mat> out;
  for (int c = colour ? 0 : 1; c < (colour ? 3 : 2); ++c) {
    cv::Mat1f ch(150, 150, 0.05f);
    for (int y = 0; y < ch.rows; ++y)
      for (int x = 0; x < ch.cols; ++x)
        if (((x / 17) + (y / 17)) % 2 == 0) ch(y, x) = light[c];
    cv::GaussianBlur(ch, ch, cv::Size(0, 0), 0.8);
    if (peak > 0) AddSpot(ch, spot_u, spot_v, 1.3, peak * weight[c]);
    cv::min(ch, 1.0f, ch);
    out.push_back(ToType(ch, CV_8U));
  }
  cv::Mat img;
  cv::merge(out, img);
  return img;
}

TEST(DetectDotsTest, SpotClippedOnANearlyClippedSquareIsFoundAndTheBoardIsNot) {
  const double u = 76.4, v = 59.3;  // inside the light square [68, 85) x [51, 68)
  for (bool colour : {false, true}) {
    const cv::Mat own = NearlyClippedBoard(u, v, 0.8, colour);
    const cv::Mat background = NearlyClippedBoard(0, 0, 0, colour);
    DotRejections rej;
    const auto dots = DetectDots(own, DotOptions{}, &rej);
    ASSERT_EQ(dots.size(), 1u) << (colour ? "BGR" : "mono");
    EXPECT_LT(NearestError(dots, u, v), 0.15) << (colour ? "BGR" : "mono");
    EXPECT_TRUE(DetectDots(background).empty());
    const auto over = DetectDotsOverBackground(own, background, DotOptions{});
    ASSERT_EQ(over.size(), 1u) << (colour ? "BGR" : "mono");
    EXPECT_LT(NearestError(over, u, v), 0.15) << (colour ? "BGR" : "mono");
  }
}

}  // namespace
}  // namespace msmcal::vision

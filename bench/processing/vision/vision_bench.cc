// Dot extraction and board detection on full 10 MP frames (3840 x 2748), against plain OpenCV.
#include <benchmark/benchmark.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "common/units.h"
#include "processing/vision/checkerboard.h"
#include "processing/vision/dots.h"

namespace {

constexpr int kWidth = 3840, kHeight = 2748;

// A mono frame: dark background, a board-like pattern of light squares, 60 Gaussian dots.
cv::Mat MakeFrame(bool with_board) {
  cv::Mat1b img(kHeight, kWidth, uchar{12});
  if (with_board) {
    const int sq = 60, x0 = 900, y0 = 500, cols = 24, rows = 29;  // squares
    cv::rectangle(img, cv::Rect(x0 - sq, y0 - sq, (cols + 2) * sq, std::min(rows + 2, 34) * sq),
                  cv::Scalar(204), cv::FILLED);
    for (int j = 0; j < std::min(rows, 32); ++j)
      for (int i = 0; i < cols; ++i)
        if ((i + j) % 2 == 0)
          cv::rectangle(img, cv::Rect(x0 + i * sq, y0 + j * sq, sq, sq), cv::Scalar(15),
                        cv::FILLED);
  }
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(50, kWidth - 50), v(50, kHeight - 50);
  for (int k = 0; k < 60; ++k) {
    const double cu = u(rng), cv_ = v(rng);
    for (int y = static_cast<int>(cv_) - 8; y <= static_cast<int>(cv_) + 8; ++y)
      for (int x = static_cast<int>(cu) - 8; x <= static_cast<int>(cu) + 8; ++x) {
        const double g =
            180 * std::exp(-((x - cu) * (x - cu) + (y - cv_) * (y - cv_)) / (2 * 2.25));
        img(y, x) = cv::saturate_cast<uchar>(img(y, x) + g);
      }
  }
  return img;
}

// Args: (board pattern + top-hat, Gaussian fit of every dot).
void BM_DetectDots(benchmark::State& state) {
  const cv::Mat img = MakeFrame(state.range(0) != 0);
  msmcal::vision::DotOptions o;
  o.background_kernel_px = state.range(0) != 0 ? 11 : 0;
  o.centre = state.range(1) != 0 ? msmcal::vision::DotCentre::kGaussianFit
                                 : msmcal::vision::DotCentre::kWeightedCentroid;
  for (auto _ : state) benchmark::DoNotOptimize(msmcal::vision::DetectDots(img, o));
}
BENCHMARK(BM_DetectDots)
    ->Args({0, 0})
    ->Args({0, 1})
    ->Args({1, 0})
    ->Args({1, 1})
    ->Unit(benchmark::kMillisecond);

// The second pass of one frame's 60 dots: their windows' background from 3 other frames (the
// same frame here, its own dots masked, which the benchmark does not mind) and the refit.
void BM_RefineDotsOnBackground(benchmark::State& state) {
  namespace v = msmcal::vision;
  const cv::Mat img = MakeFrame(true);
  const auto dots = v::DetectDots(img);
  std::vector<cv::Rect> windows;
  for (const auto& d : dots) windows.push_back(v::DotFitWindow(d, img.size(), v::DotOptions{}));
  for (auto _ : state) {
    std::vector<v::BackgroundPatch> bg(windows.size());
    for (int k = 0; k < 3; ++k) {
      const auto c = v::BackgroundContribution(img, {}, windows);
      for (size_t w = 0; w < windows.size(); ++w) bg[w].Add(c[w]);
    }
    for (size_t w = 0; w < windows.size(); ++w) {
      v::Dot d = dots[w];
      benchmark::DoNotOptimize(
          v::RefineDotOnBackground(v::ReadDotSignal(img, windows[w]), bg[w], {}, &d));
    }
  }
  state.counters["dots"] = static_cast<double>(dots.size());
}
BENCHMARK(BM_RefineDotsOnBackground)->Unit(benchmark::kMillisecond);

void BM_DetectDotsOpenCvReference(benchmark::State& state) {
  const cv::Mat img = MakeFrame(false);
  for (auto _ : state) benchmark::DoNotOptimize(msmcal::vision::DetectDotsOpenCvReference(img));
}
BENCHMARK(BM_DetectDotsOpenCvReference)->Unit(benchmark::kMillisecond);

void BM_DetectCheckerboardCoarseToFine(benchmark::State& state) {
  const cv::Mat img = MakeFrame(true);
  for (auto _ : state) benchmark::DoNotOptimize(msmcal::vision::DetectCheckerboard(img, {23, 28}));
}
BENCHMARK(BM_DetectCheckerboardCoarseToFine)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_FindChessboardCornersSBFullResolution(benchmark::State& state) {
  const cv::Mat img = MakeFrame(true);
  std::vector<cv::Point2f> corners;
  for (auto _ : state)
    benchmark::DoNotOptimize(cv::findChessboardCornersSB(img, cv::Size(23, 28), corners, 0));
}
BENCHMARK(BM_FindChessboardCornersSBFullResolution)->Unit(benchmark::kMillisecond)->Iterations(1);

// ---- A board that only a later detector of the chain finds, with and without a hint ----
// A 23 x 28 board of ~14 x 10 px squares in a 1600 x 1200 frame, slanted, defocused and noisy (a
// world board seen at a slant from afar): the whole chain (counter `method`: the BoardMethod that
// found it), and with the hint another frame of the view gives (vision::BoardHint: that detector on
// the board's region only, as the solver searches every frame of a view after its first).
cv::Mat SmallSquaresFrame() {
  // The board drawn with 40 px squares, then seen at a slant: 0.35 across, 0.25 along (and a
  // little perspective), rotated by 20 deg: squares of ~14 x 10 px, which the coarse search
  // misses and SB at full resolution finds (at 0.32 x 0.23 no detector of the chain finds it).
  const int sq = 40, cols = 24, rows = 29;
  cv::Mat1b flat((rows + 4) * sq, (cols + 4) * sq, uchar{200});
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i)
      if ((i + j) % 2 == 0)
        cv::rectangle(flat, cv::Rect((i + 2) * sq, (j + 2) * sq, sq, sq), cv::Scalar(30),
                      cv::FILLED);
  const double a = 20 * msmcal::common::kRadPerDeg;
  const cv::Matx33d rot(std::cos(a), -std::sin(a), 700, std::sin(a), std::cos(a), 420, 0, 0, 1);
  const cv::Matx33d slant(0.35, 0, 0, 0, 0.25, 0, 1e-5, 0, 1);
  cv::Mat1b img(1200, 1600, uchar{40});
  cv::warpPerspective(flat, img, rot * slant, img.size(), cv::INTER_AREA, cv::BORDER_TRANSPARENT);
  cv::Mat blurred, noise(img.size(), CV_16S), out;
  cv::GaussianBlur(img, blurred, cv::Size(0, 0), 0.8);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::NORMAL, 0, 3);
  cv::add(blurred, noise, out, cv::noArray(), CV_8U);
  return out;
}

void BM_SmallSquares_WholeChain(benchmark::State& state) {
  const cv::Mat img = SmallSquaresFrame();
  int method = -1;
  for (auto _ : state) {
    const auto det = msmcal::vision::DetectCheckerboard(img, {23, 28});
    method = det ? static_cast<int>(det->method) : -1;
  }
  state.counters["method"] = method;
}
BENCHMARK(BM_SmallSquares_WholeChain)->Unit(benchmark::kMillisecond)->Iterations(2);

void BM_SmallSquares_Hinted(benchmark::State& state) {
  const cv::Mat img = SmallSquaresFrame();
  const auto first = msmcal::vision::DetectCheckerboard(img, {23, 28});
  if (!first) {
    state.SkipWithError("the whole chain did not find the board");
    return;
  }
  const msmcal::vision::BoardHint hint = msmcal::vision::HintFrom(*first, img.size(), {});
  int hinted = 0;
  for (auto _ : state) {
    const auto det =
        msmcal::vision::DetectCheckerboard(img, {23, 28}, {}, cv::Mat(), nullptr, &hint);
    hinted = det && det->hinted;
  }
  state.counters["method"] = static_cast<int>(first->method);
  state.counters["hinted"] = hinted;
}
BENCHMARK(BM_SmallSquares_Hinted)->Unit(benchmark::kMillisecond)->Iterations(2);

// ---- How often each detector finds a board, and at what cost, over varied boards ----
// 60 boards (13 x 8 inner corners, canonical colouring) warped into 1600 x 1200 frames: squares
// 8-60 px, tilt up to 60 deg about a random axis, defocus 0-2.5 px, vignetting up to 50 %,
// uneven light (a linear ramp), noise; a second board-like distractor beside it in half of them.
// Counters: found (of 60) and mean seconds per frame, per detector: SB at full resolution (OpenCV's
// reference), the classic detector, and msmcal's fallback chain.
struct VariedBoard {
  cv::Mat image;
};

std::vector<VariedBoard> VariedBoards() {
  std::vector<VariedBoard> out;
  std::mt19937 rng(7);
  auto u = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  const int cols = 13, rows = 8, sq = 40;  // flat board image: (cols + 3) x (rows + 3) squares
  cv::Mat1f flat((rows + 3) * sq, (cols + 3) * sq, 0.85f);
  for (int j = -1; j <= rows - 1; ++j)
    for (int i = -1; i <= cols - 1; ++i)
      if ((i + j + 2) % 2 == 0)
        flat(cv::Rect((i + 2) * sq - sq / 2, (j + 2) * sq - sq / 2, sq, sq)) = 0.08f;
  for (int k = 0; k < 60; ++k) {
    const double square_px = std::exp(u(std::log(8.0), std::log(60.0)));
    const double tilt = msmcal::common::DegToRad(u(0, 60)), axis = u(0, M_PI),
                 roll = u(0, 2 * M_PI);
    const double w = (cols + 3) * square_px, h = (rows + 3) * square_px;
    // Corners of the board in the image: a tilted rectangle under a weak perspective.
    std::vector<cv::Point2f> src = {
        {0, 0}, {float(flat.cols), 0}, {float(flat.cols), float(flat.rows)}, {0, float(flat.rows)}};
    std::vector<cv::Point2f> dst;
    const cv::Point2f c(800 + u(-200, 200), 600 + u(-150, 150));
    for (const auto& p : src) {
      double x = (p.x / flat.cols - 0.5) * w, y = (p.y / flat.rows - 0.5) * h;
      // Tilt: foreshorten along `axis`, with a perspective gain on the far side.
      const double along = x * std::cos(axis) + y * std::sin(axis);
      const double across = -x * std::sin(axis) + y * std::cos(axis);
      const double depth = 1.0 + 0.4 * std::sin(tilt) * along / std::max(w, h);
      const double a2 = along * std::cos(tilt) / depth, c2 = across / depth;
      x = a2 * std::cos(axis) - c2 * std::sin(axis);
      y = a2 * std::sin(axis) + c2 * std::cos(axis);
      dst.emplace_back(static_cast<float>(c.x + x * std::cos(roll) - y * std::sin(roll)),
                       static_cast<float>(c.y + x * std::sin(roll) + y * std::cos(roll)));
    }
    cv::Mat1f img(1200, 1600, 0.05f);
    cv::warpPerspective(flat, img, cv::getPerspectiveTransform(src, dst), img.size(),
                        cv::INTER_AREA, cv::BORDER_TRANSPARENT);
    if (k % 2 == 1)  // a distractor: a smaller checker patch in a corner
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 5; ++i)
          if ((i + j) % 2 == 0) img(cv::Rect(40 + i * 20, 40 + j * 20, 20, 20)) = 0.8f;
    const double blur = u(0, 2.5);
    if (blur > 0.3) cv::GaussianBlur(img, img, cv::Size(0, 0), blur);
    const double vig = u(0, 0.5), ramp = u(-0.3, 0.3);
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const double r2 =
            (std::pow(x - 800.0, 2) + std::pow(y - 600.0, 2)) / (800.0 * 800 + 600 * 600);
        img(y, x) = static_cast<float>(img(y, x) * (1 - vig * r2) * (1 + ramp * (x - 800.0) / 800));
      }
    cv::Mat1f noise(img.size());
    cv::randn(noise, 0, u(0.002, 0.02));
    img += noise;
    cv::Mat g;
    img.convertTo(g, CV_8U, 255);
    out.push_back({g});
  }
  return out;
}

void RunDetector(benchmark::State& state, int which) {
  static const std::vector<VariedBoard> boards = VariedBoards();
  int found = 0, frames = 0;
  for (auto _ : state) {
    found = 0;
    frames = 0;
    for (const auto& b : boards) {
      std::vector<cv::Point2f> corners;
      bool ok = false;
      if (which == 0)
        ok = cv::findChessboardCornersSB(b.image, cv::Size(13, 8), corners, 0);
      else if (which == 1)
        ok = cv::findChessboardCorners(
            b.image, cv::Size(13, 8), corners,
            cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK);
      else
        ok = msmcal::vision::DetectCheckerboard(b.image, {13, 8}).has_value();
      found += ok;
      ++frames;
    }
  }
  state.counters["found"] = found;
  state.counters["of"] = frames;
  state.counters["s_per_frame"] =
      benchmark::Counter(static_cast<double>(frames) * state.iterations(),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
void BM_VariedBoards_SbFullResolution(benchmark::State& s) { RunDetector(s, 0); }
void BM_VariedBoards_Classic(benchmark::State& s) { RunDetector(s, 1); }
void BM_VariedBoards_MsmcalChain(benchmark::State& s) { RunDetector(s, 2); }
BENCHMARK(BM_VariedBoards_SbFullResolution)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_VariedBoards_Classic)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_VariedBoards_MsmcalChain)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

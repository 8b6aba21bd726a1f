// Dot extraction and board detection on full 10 MP frames (3840 x 2748), against plain OpenCV.
#include <benchmark/benchmark.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

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

}  // namespace

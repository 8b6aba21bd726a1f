#include "processing/vision/checkerboard.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "processing/vision/corner_fit.h"

namespace msmcal::vision {
namespace {

double MeanAround(const cv::Mat& gray, const Eigen::Vector2d& p, int half) {
  const int x0 = std::clamp(static_cast<int>(std::lround(p.x())) - half, 0, gray.cols - 1);
  const int y0 = std::clamp(static_cast<int>(std::lround(p.y())) - half, 0, gray.rows - 1);
  const int x1 = std::clamp(static_cast<int>(std::lround(p.x())) + half, 0, gray.cols - 1);
  const int y1 = std::clamp(static_cast<int>(std::lround(p.y())) + half, 0, gray.rows - 1);
  return cv::mean(gray(cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1)))[0];
}

// `gray` where `mask` (optional) is nonzero, mid-grey (128 in 8-bit units) elsewhere.
cv::Mat FillOutsideMask(const cv::Mat& gray, const cv::Mat& mask) {
  if (mask.empty()) return gray;
  cv::Mat masked(gray.size(), gray.type(), cv::Scalar(128));
  gray.copyTo(masked, mask);
  return masked;
}

}  // namespace

std::string CheckerboardOptions::Validate() const {
  std::ostringstream s;
  if (coarse_max_side_px < 200)
    s << "coarse_max_side_px = " << coarse_max_side_px << " must be >= 200";
  else if (classic_max_corners < 0)
    s << "classic_max_corners = " << classic_max_corners << " must be >= 0";
  else if (upscale_max_side_px < 0)
    s << "upscale_max_side_px = " << upscale_max_side_px << " must be >= 0";
  else if (!(max_refine_shift_squares > 0 && max_refine_shift_squares <= 1))
    s << "max_refine_shift_squares = " << max_refine_shift_squares << " must be in (0, 1]";
  else if (!(refine_window_squares > 0 && refine_window_squares <= 0.5))
    s << "refine_window_squares = " << refine_window_squares << " must be in (0, 0.5]";
  else if (!(refine_window_min_px >= 0 && refine_window_min_px <= 15))
    s << "refine_window_min_px = " << refine_window_min_px << " must be in [0, 15]";
  else if (!(fit_max_radius_px >= 2 && fit_max_radius_px <= 15))
    s << "fit_max_radius_px = " << fit_max_radius_px << " must be in [2, 15]";
  else if (!(min_contrast_levels >= 0 && min_contrast_levels <= 128))
    s << "min_contrast_levels = " << min_contrast_levels << " must be in [0, 128]";
  else if (!(max_grid_irregularity_squares > 0 && max_grid_irregularity_squares <= 1))
    s << "max_grid_irregularity_squares = " << max_grid_irregularity_squares
      << " must be in (0, 1]";
  else if (textured_regions < 0 || textured_regions > 16)
    s << "textured_regions = " << textured_regions << " must be in [0, 16]";
  else if (!(hint_margin_squares >= 1 && hint_margin_squares <= 20))
    s << "hint_margin_squares = " << hint_margin_squares << " must be in [1, 20]";
  return s.str();
}

cv::Mat ToGray32F(const cv::Mat& image, const cv::Mat& mask) {
  if (image.channels() != 1 && image.channels() != 3)
    throw std::invalid_argument("ToGray32F: expected 1 or 3 channels, got " +
                                std::to_string(image.channels()));
  if (image.depth() != CV_8U && image.depth() != CV_16U)
    throw std::invalid_argument("ToGray32F: expected 8- or 16-bit image");
  cv::Mat f;
  image.convertTo(f, CV_32F, image.depth() == CV_16U ? 1.0 / 257.0 : 1.0);
  cv::Mat gray;
  if (f.channels() == 3)
    cv::cvtColor(f, gray, cv::COLOR_BGR2GRAY);
  else
    gray = f;
  return FillOutsideMask(gray, mask);
}

cv::Mat ToGray8(const cv::Mat& image) {
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 1) {
    gray = image;
  } else {
    throw std::invalid_argument("ToGray8: expected 1 or 3 channels, got " +
                                std::to_string(image.channels()));
  }
  if (gray.depth() == CV_16U) {
    cv::Mat g8;
    gray.convertTo(g8, CV_8U, 1.0 / 257.0);
    return g8;
  }
  if (gray.depth() != CV_8U) throw std::invalid_argument("ToGray8: expected 8- or 16-bit image");
  return gray;
}

cv::Mat ToBgr8(const cv::Mat& image, const std::string& what) {
  if (image.empty()) throw std::invalid_argument(what + ": empty image");
  if (image.depth() != CV_8U && image.depth() != CV_16U)
    throw std::invalid_argument(what + ": image depth must be 8 or 16 bit");
  if (image.channels() != 1 && image.channels() != 3)
    throw std::invalid_argument(what + ": image must have 1 or 3 channels, not " +
                                std::to_string(image.channels()));
  cv::Mat eight;
  if (image.depth() == CV_16U)
    image.convertTo(eight, CV_8U, 1.0 / 257.0);
  else
    eight = image;
  cv::Mat bgr;
  if (eight.channels() == 1)
    cv::cvtColor(eight, bgr, cv::COLOR_GRAY2BGR);
  else
    bgr = eight.clone();
  return bgr;
}

std::vector<Eigen::Vector2d> CanonicalCornerOrder(const std::vector<Eigen::Vector2d>& grid,
                                                  BoardSize size, const cv::Mat& gray) {
  const int cols = size.cols, rows = size.rows;
  auto at = [&](const std::vector<Eigen::Vector2d>& g, int r, int c) -> const Eigen::Vector2d& {
    return g[static_cast<size_t>(r * cols + c)];
  };
  std::vector<Eigen::Vector2d> g = grid;
  // Handedness: with X along c and Y along r, Z = X x Y must point away from the camera, i.e.
  // the image-space cross product (v axis down) is positive.
  const Eigen::Vector2d dx = at(g, 0, cols - 1) - at(g, 0, 0);
  const Eigen::Vector2d dy = at(g, rows - 1, 0) - at(g, 0, 0);
  if (dx.x() * dy.y() - dx.y() * dy.x() < 0) {
    std::vector<Eigen::Vector2d> flipped(g.size());
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < cols; ++c) flipped[r * cols + c] = at(g, rows - 1 - r, c);
    g.swap(flipped);
  }
  // Origin: of the two corners compatible with the handedness, the one whose diagonally outward
  // square is dark.
  const Eigen::Vector2d a = at(g, 0, 0), a_in = at(g, 1, 1);
  const Eigen::Vector2d b = at(g, rows - 1, cols - 1), b_in = at(g, rows - 2, cols - 2);
  const int half = std::max(1, static_cast<int>(0.15 * (a - a_in).norm()));
  const double shade_a = MeanAround(gray, a + 0.5 * (a - a_in), half);
  const double shade_b = MeanAround(gray, b + 0.5 * (b - b_in), half);
  if (shade_b < shade_a) std::reverse(g.begin(), g.end());
  return g;
}

namespace {

// Median distance between neighbouring corners of a row-major rows x cols grid.
// Distances between neighbouring corners along rows and columns.
std::vector<double> NeighbourDistances(const std::vector<cv::Point2f>& g, BoardSize size) {
  std::vector<double> d;
  for (int r = 0; r < size.rows; ++r)
    for (int c = 0; c < size.cols; ++c) {
      const auto& p = g[r * size.cols + c];
      if (c + 1 < size.cols) d.push_back(cv::norm(g[r * size.cols + c + 1] - p));
      if (r + 1 < size.rows) d.push_back(cv::norm(g[(r + 1) * size.cols + c] - p));
    }
  return d;
}

double MedianSpacing(const std::vector<cv::Point2f>& g, BoardSize size) {
  std::vector<double> d = NeighbourDistances(g, size);
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

// Largest second difference along rows and columns, in units of the local spacing: a true grid
// under perspective and lens distortion stays far below the limit, a grid strung over the wrong
// points does not.
double GridIrregularity(const std::vector<cv::Point2f>& g, BoardSize size) {
  double worst = 0;
  auto at = [&](int r, int c) { return g[r * size.cols + c]; };
  for (int r = 0; r < size.rows; ++r)
    for (int c = 0; c < size.cols; ++c) {
      if (c > 0 && c + 1 < size.cols) {
        const double s = 0.5 * (cv::norm(at(r, c + 1) - at(r, c - 1)));
        worst = std::max(worst,
                         cv::norm(at(r, c - 1) + at(r, c + 1) - 2 * at(r, c)) / std::max(s, 1e-6));
      }
      if (r > 0 && r + 1 < size.rows) {
        const double s = 0.5 * (cv::norm(at(r + 1, c) - at(r - 1, c)));
        worst = std::max(worst,
                         cv::norm(at(r - 1, c) + at(r + 1, c) - 2 * at(r, c)) / std::max(s, 1e-6));
      }
    }
  return worst;
}

// cornerSubPix's half window for a grid (CheckerboardOptions::refine_window_squares): from the
// smallest distance between neighbouring corners along rows and columns, at least
// refine_window_min_px (the blurred edges next to the corner), never beyond half that distance
// (the next corner).
double RefineHalfWindow(const std::vector<cv::Point2f>& g, BoardSize size,
                        const CheckerboardOptions& options) {
  const std::vector<double> d = NeighbourDistances(g, size);
  const double min_spacing = *std::min_element(d.begin(), d.end());
  return std::min(
      std::max(min_spacing * options.refine_window_squares, options.refine_window_min_px),
      0.5 * min_spacing);
}

// Runs one detector of the chain on `gray` scaled by `scale` (1: as is); corners in full
// resolution pixels (pixel-centre convention: p_full = (p_scaled + 0.5) / scale - 0.5).
// `region` (not empty): the detector sees only that part of `gray`.
bool RunDetector(const cv::Mat& whole, BoardSize size, BoardMethod method, double scale,
                 const cv::Rect& region, std::vector<cv::Point2f>* found) {
  const cv::Mat gray = region.empty() ? whole : whole(region).clone();
  cv::Mat img;
  if (scale < 1.0)
    cv::resize(gray, img, cv::Size(), scale, scale, cv::INTER_AREA);
  else if (scale > 1.0)
    cv::resize(gray, img, cv::Size(), scale, scale, cv::INTER_LINEAR);
  else
    img = gray;
  const cv::Size pattern(size.cols, size.rows);
  bool ok = false;
  switch (method) {
    case BoardMethod::kSbCoarse:
    case BoardMethod::kSbFull:
      ok = cv::findChessboardCornersSB(img, pattern, *found, 0);
      break;
    case BoardMethod::kSbUpscaled:
      // Plain first, then with histogram normalisation: each finds boards the other misses
      // (normalisation fails on a blurred, oblique 23 x 28 board with ~14 px squares that the
      // plain detector finds at x1.5 and x2; it helps on low-contrast small boards).
      ok = cv::findChessboardCornersSB(img, pattern, *found, 0) ||
           cv::findChessboardCornersSB(img, pattern, *found, cv::CALIB_CB_NORMALIZE_IMAGE);
      break;
    case BoardMethod::kContrastCheck:
      return false;
    case BoardMethod::kClassic:
      // FAST_CHECK: without it, an image where the board is not found costs tens of seconds
      // in the detector's dilation and threshold loops (measured: 35 s on 1600 x 1200).
      ok = cv::findChessboardCorners(
          img, pattern, *found,
          cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK);
      break;
  }
  if (!ok || found->size() != static_cast<size_t>(size.cols * size.rows)) return false;
  if (scale != 1.0)
    for (auto& p : *found) {
      p.x = static_cast<float>((p.x + 0.5) / scale - 0.5);
      p.y = static_cast<float>((p.y + 0.5) / scale - 0.5);
    }
  for (auto& p : *found) {
    p.x += static_cast<float>(region.x);
    p.y += static_cast<float>(region.y);
  }
  return true;
}

// The span of an 8-bit image's grey levels between their 0.1 and 99.9 percentiles, after a 3 x 3
// median (hot and dead pixels gone) and 4 x 4 area averaging (noise down by 4); a square of 8 px
// keeps its level.
double GreyLevelSpan(const cv::Mat& gray) {
  cv::Mat small = gray;
  if (gray.cols >= 8 && gray.rows >= 8) {
    cv::Mat median;
    cv::medianBlur(gray, median, 3);
    cv::resize(median, small, cv::Size(), 0.25, 0.25, cv::INTER_AREA);
  }
  std::array<int, 256> hist{};
  for (int r = 0; r < small.rows; ++r) {
    const uint8_t* row = small.ptr<uint8_t>(r);
    for (int c = 0; c < small.cols; ++c) ++hist[row[c]];
  }
  const double total = static_cast<double>(small.total());
  auto level_at = [&](double fraction) {
    double seen = 0;
    for (int v = 0; v < 256; ++v) {
      seen += hist[v];
      if (seen >= fraction * total) return v;
    }
    return 255;
  };
  return level_at(0.999) - level_at(0.001);
}

}  // namespace

const char* ToString(BoardMethod method) {
  switch (method) {
    case BoardMethod::kSbCoarse:
      return "sb_coarse";
    case BoardMethod::kSbFull:
      return "sb_full";
    case BoardMethod::kSbUpscaled:
      return "sb_upscaled";
    case BoardMethod::kClassic:
      return "classic";
    case BoardMethod::kContrastCheck:
      return "contrast_check";
  }
  return "?";
}

std::vector<cv::Rect> TexturedRegions(const cv::Mat& gray, BoardSize size, int max_regions) {
  if (gray.type() != CV_8UC1) throw std::invalid_argument("TexturedRegions: expected 8-bit grey");
  if (max_regions <= 0 || gray.empty()) return {};
  const int side = std::max(gray.cols, gray.rows);
  const int w = std::clamp(side / 60, 9, 61) | 1;  // the window; odd
  cv::Mat f, ix, iy;
  gray.convertTo(f, CV_32F);
  cv::Sobel(f, ix, CV_32F, 1, 0, 3);
  cv::Sobel(f, iy, CV_32F, 0, 1, 3);
  cv::Mat xx = ix.mul(ix), yy = iy.mul(iy), xy = ix.mul(iy);
  for (cv::Mat* m : {&xx, &yy, &xy}) cv::boxFilter(*m, *m, -1, cv::Size(w, w));
  const cv::Mat half_trace = (xx + yy) * 0.5;
  cv::Mat disc;
  cv::sqrt(cv::max(half_trace.mul(half_trace) - (xx.mul(yy) - xy.mul(xy)), 0.0), disc);
  const cv::Mat smaller = half_trace - disc;
  double top = 0;
  cv::minMaxLoc(smaller, nullptr, &top);
  if (!(top > 0)) return {};
  // The median of the eigenvalue map (a sample of it: every 4th pixel each way).
  std::vector<float> sample;
  for (int y = 0; y < smaller.rows; y += 4)
    for (int x = 0; x < smaller.cols; x += 4) sample.push_back(smaller.at<float>(y, x));
  std::nth_element(sample.begin(), sample.begin() + sample.size() / 2, sample.end());
  const double median = std::max<double>(sample[sample.size() / 2], 1e-6 * top);
  cv::Mat mask = smaller > std::sqrt(median * top);
  // A board's squares larger than the window leave holes in its mask: closed by the window.
  cv::morphologyEx(mask, mask, cv::MORPH_CLOSE,
                   cv::getStructuringElement(cv::MORPH_RECT, cv::Size(w, w)));
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  const cv::Rect image(0, 0, gray.cols, gray.rows);
  const int min_side = 4 * std::min(size.cols, size.rows);  // px: 4 per inner corner
  std::vector<std::pair<int, cv::Rect>> regions;
  for (int c = 1; c < n; ++c) {
    const cv::Rect r(stats.at<int>(c, cv::CC_STAT_LEFT), stats.at<int>(c, cv::CC_STAT_TOP),
                     stats.at<int>(c, cv::CC_STAT_WIDTH), stats.at<int>(c, cv::CC_STAT_HEIGHT));
    const cv::Rect grown = ((r + cv::Size(2 * w, 2 * w)) - cv::Point(w, w)) & image;
    // A point-like feature (a spot, a plate's corner) makes a patch about one window across.
    if (std::min(r.width, r.height) < 2 * w || std::min(grown.width, grown.height) < min_side ||
        grown.area() < 16 * size.cols * size.rows || grown.area() > 0.8 * image.area())
      continue;
    regions.emplace_back(stats.at<int>(c, cv::CC_STAT_AREA), grown);
  }
  std::stable_sort(regions.begin(), regions.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<cv::Rect> out;
  for (const auto& [area, r] : regions)
    if (static_cast<int>(out.size()) < max_regions) out.push_back(r);
  return out;
}

std::optional<CheckerboardDetection> DetectCheckerboard(const cv::Mat& image, BoardSize size,
                                                        const CheckerboardOptions& options,
                                                        const cv::Mat& mask,
                                                        std::vector<BoardAttempt>* attempts,
                                                        const BoardHint* hint) {
  if (const std::string err = options.Validate(); !err.empty())
    throw std::invalid_argument("CheckerboardOptions: " + err);
  if (size.cols < 2 || size.rows < 2)
    throw std::invalid_argument("DetectCheckerboard: board needs >= 2x2 inner corners");
  const cv::Mat gray = FillOutsideMask(ToGray8(image), mask);
  if (options.min_contrast_levels > 0) {
    const double span = GreyLevelSpan(gray);
    if (span < options.min_contrast_levels) {
      if (attempts) {
        std::ostringstream why;
        why << "no contrast: grey levels span " << span
            << " (0.1-99.9 percentiles, 3x3 median, 4x4 averaged) < boards.min_contrast_levels "
            << options.min_contrast_levels << ": a black, blank or saturated frame";
        attempts->push_back({BoardMethod::kContrastCheck, 0.25, false, false, why.str(), {}});
      }
      return std::nullopt;
    }
  }
  // The chain: SB on a ladder of coarse scales (it succeeds or fails somewhat erratically with
  // the square size in pixels), SB at full resolution, SB upscaled (small squares), classic.
  const int side = std::max(gray.cols, gray.rows);
  struct Try {
    BoardMethod method;
    double scale;
    cv::Rect region;        // empty: the whole image
    bool textured = false;  // a region of TexturedRegions (not a hint's)
  };
  std::vector<Try> chain;
  // A hint first: its detector on its region only. The region must hold the board's corners
  // with room around them (at least 4 x 4 px per inner corner).
  cv::Rect hint_region;  // empty: no usable hint
  if (hint) {
    const cv::Rect region = hint->region & cv::Rect(0, 0, gray.cols, gray.rows);
    if (region.width >= 4 * size.cols && region.height >= 4 * size.rows &&
        region.area() < gray.cols * gray.rows) {
      chain.push_back({hint->method, hint->scale, region});
      hint_region = region;
    }
  }
  const size_t hinted = chain.size();
  for (double f : {1.0, 0.7, 1.4}) {
    const double s = f * options.coarse_max_side_px / side;
    if (s < 1.0) chain.push_back({BoardMethod::kSbCoarse, s, {}});
  }
  if (options.try_sb_full || chain.size() == hinted)
    chain.push_back({BoardMethod::kSbFull, 1.0, {}});
  // Then, where SB found nothing on the whole image, the image's checker-like regions
  // (TexturedRegions; SB full, SB upscaled, classic on each), before the costly whole-image
  // searches: on a 1920 x 1200 frame the classic detector spent up to 200 s failing.
  const size_t regions_at = chain.size();
  // The classic detector's quad grouping grows badly with the board: on a 23 x 28 board it took
  // minutes on some simulated frames where it was asked; boards above classic_max_corners skip it.
  if (options.try_classic && size.cols * size.rows <= options.classic_max_corners)
    chain.push_back({BoardMethod::kClassic, 1.0, {}});
  if (options.try_sb_upscaled && 2 * side <= options.upscale_max_side_px)
    chain.push_back({BoardMethod::kSbUpscaled, 2.0, {}});
  // Whether the hinted detector found a grid in the hint's region (refused or not): the board is
  // there. The classic detector then runs on that region, not on the whole image: where it fails
  // there, the whole image costs far more for nothing (a 21 x 14 board of 12 px squares, 1920 x
  // 1200 mono: 0.04 s on the region, 200 s failing on the whole frame; docs/solver.md), and it
  // does not run twice on the same region.
  bool board_in_hint_region = false;
  for (size_t k = 0;; ++k) {
    if (k == regions_at) {
      std::vector<Try> tries;
      for (const cv::Rect& r : TexturedRegions(gray, size, options.textured_regions)) {
        tries.push_back({BoardMethod::kSbFull, 1.0, r, true});
        // x3 too: a 25 x 18 board of 7-10 px squares (1600 x 1200) that SB finds on its region
        // x3 and not x2, whatever the margin around it.
        for (double up : {2.0, 3.0})
          if (options.try_sb_upscaled &&
              up * std::max(r.width, r.height) <= options.upscale_max_side_px)
            tries.push_back({BoardMethod::kSbUpscaled, up, r, true});
        if (options.try_classic && size.cols * size.rows <= options.classic_max_corners)
          tries.push_back({BoardMethod::kClassic, 1.0, r, true});
      }
      chain.insert(chain.begin() + static_cast<std::ptrdiff_t>(k), tries.begin(), tries.end());
    }
    if (k >= chain.size()) break;
    const auto [method, scale, chain_region, textured] = chain[k];
    cv::Rect region = chain_region;
    if (method == BoardMethod::kClassic && k >= hinted && !textured &&
        (board_in_hint_region || (hint && hint->fixed && !hint_region.empty()))) {
      if (hint->method == BoardMethod::kClassic && hint->scale == 1.0) continue;
      region = hint_region;
    }
    BoardAttempt attempt{method, scale, false, false, "", region, textured};
    std::vector<cv::Point2f> found;
    const auto started = std::chrono::steady_clock::now();
    attempt.found = RunDetector(gray, size, method, scale, region, &found);
    attempt.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    if (k < hinted && attempt.found) board_in_hint_region = true;
    if (!attempt.found) {
      if (attempts) attempts->push_back(attempt);
      continue;
    }
    const double spacing = MedianSpacing(found, size);
    // A grid whose corners sit off their neighbours' line by at most kMaxRawIrregularity squares
    // may be the right grid with rough corners (the classic detector's corners come from its
    // quads' vertices: up to 0.6 squares off on a board of 12 px squares, where another frame of
    // the same view gave 0.07): it is judged after the refinement, which moves each corner at most
    // half a square. Beyond that it is strung over the wrong points.
    constexpr double kMaxRawIrregularity = 1.0;
    const double raw_irregularity = GridIrregularity(found, size);
    if (raw_irregularity > std::max(options.max_grid_irregularity_squares, kMaxRawIrregularity)) {
      std::ostringstream why;
      why << "grid irregular: a corner " << raw_irregularity
          << " squares off its neighbours' line (> " << options.max_grid_irregularity_squares
          << ")";
      attempt.note = why.str();
      if (attempts) attempts->push_back(attempt);
      continue;
    }
    const std::vector<cv::Point2f> before = found;
    const auto refine = [&](std::vector<cv::Point2f>* corners) {
      const double half = RefineHalfWindow(*corners, size, options);
      const int win = std::clamp(static_cast<int>(std::lround(half)), 2, 15);
      cv::cornerSubPix(gray, *corners, cv::Size(win, win), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 40, 1e-3));
      return std::pair<double, int>(half, win);
    };
    auto [half, win] = refine(&found);
    if (raw_irregularity > options.max_grid_irregularity_squares) {
      const double refined_irregularity = GridIrregularity(found, size);
      if (refined_irregularity > options.max_grid_irregularity_squares) {
        std::ostringstream why;
        why << "grid irregular: a corner " << raw_irregularity
            << " squares off its neighbours' line (> " << options.max_grid_irregularity_squares
            << "), " << refined_irregularity << " after sub-pixel refinement";
        attempt.note = why.str();
        if (attempts) attempts->push_back(attempt);
        continue;
      }
      // The rough corners' smallest spacing set the window: once more, with the window of the
      // refined grid (what the same board gets in a frame where the detector was not rough).
      std::tie(half, win) = refine(&found);
      std::ostringstream why;
      why << "rough grid (a corner " << raw_irregularity << " squares off its neighbours' line), "
          << GridIrregularity(found, size) << " after sub-pixel refinement";
      attempt.note = why.str();
    }
    double shift = 0;
    for (size_t i = 0; i < found.size(); ++i)
      shift = std::max<double>(shift, cv::norm(found[i] - before[i]));
    if (shift > options.max_refine_shift_squares * spacing) {
      std::ostringstream why;
      why << "sub-pixel refinement moved a corner " << shift << " px (> "
          << options.max_refine_shift_squares << " of a " << spacing << " px square)";
      attempt.note = why.str();
      if (attempts) attempts->push_back(attempt);
      continue;
    }
    attempt.accepted = true;
    if (attempts) attempts->push_back(attempt);
    std::vector<Eigen::Vector2d> grid;
    grid.reserve(found.size());
    for (const auto& p : found) grid.emplace_back(p.x, p.y);
    int corners_fitted = 0;
    if (options.fit_corners) {
      const cv::Mat levels = ToGray32F(image, mask);
      CornerFitOptions fit_options;
      fit_options.max_radius_px = options.fit_max_radius_px;
      const auto at = [&](int r, int c) { return grid[r * size.cols + c]; };
      std::vector<Eigen::Vector2d> fitted = grid;  // directions from the unfitted neighbours
      for (int r = 0; r < size.rows; ++r)
        for (int c = 0; c < size.cols; ++c) {
          const Eigen::Vector2d row_dir =
              c + 1 < size.cols ? at(r, c + 1) - at(r, c) : at(r, c) - at(r, c - 1);
          const Eigen::Vector2d col_dir =
              r + 1 < size.rows ? at(r + 1, c) - at(r, c) : at(r, c) - at(r - 1, c);
          if (const auto f = FitCorner(levels, at(r, c), row_dir, col_dir, half, fit_options)) {
            fitted[r * size.cols + c] = f->px;
            ++corners_fitted;
          }
        }
      grid = std::move(fitted);
    }
    CheckerboardDetection det;
    det.corners_px = CanonicalCornerOrder(grid, size, gray);
    det.refine_half_window_px = win;
    det.corners_fitted = corners_fitted;
    det.method = method;
    det.scale = scale;
    det.hinted = !region.empty() && !textured;
    det.square_px = spacing;
    return det;
  }
  return std::nullopt;
}

std::vector<char> CornersClearOfSpots(const CheckerboardDetection& board,
                                      const std::vector<cv::Rect>& spot_boxes) {
  std::vector<char> clear(board.corners_px.size(), 1);
  const double window = std::sqrt(2.0) * board.refine_half_window_px;
  for (const auto& box : spot_boxes) {
    const Eigen::Vector2d centre(box.x + 0.5 * (box.width - 1), box.y + 0.5 * (box.height - 1));
    const double reach = 0.5 * std::hypot(box.width, box.height) + 3.0 + window;
    for (size_t i = 0; i < clear.size(); ++i)
      if ((board.corners_px[i] - centre).norm() < reach) clear[i] = 0;
  }
  return clear;
}

cv::Mat BoardHomography(const CheckerboardDetection& board, BoardSize size) {
  std::vector<cv::Point2f> src, dst;
  for (int r = 0; r < size.rows; ++r)
    for (int c = 0; c < size.cols; ++c) {
      src.emplace_back(static_cast<float>(c), static_cast<float>(r));
      const auto& p = board.corners_px[r * size.cols + c];
      dst.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
  return cv::findHomography(src, dst, 0);
}

std::vector<Eigen::Vector2d> SquaresOutline(const CheckerboardDetection& board, BoardSize size,
                                            double margin) {
  const cv::Mat h = BoardHomography(board, size);
  const double lo = -1 - margin;
  const std::vector<cv::Point2f> outer = {
      {static_cast<float>(lo), static_cast<float>(lo)},
      {static_cast<float>(size.cols + margin), static_cast<float>(lo)},
      {static_cast<float>(size.cols + margin), static_cast<float>(size.rows + margin)},
      {static_cast<float>(lo), static_cast<float>(size.rows + margin)}};
  std::vector<cv::Point2f> mapped;
  std::vector<Eigen::Vector2d> out;
  if (h.empty()) return out;
  cv::perspectiveTransform(outer, mapped, h);
  for (const auto& p : mapped) out.emplace_back(p.x, p.y);
  return out;
}

BoardHint HintFrom(const CheckerboardDetection& board, cv::Size image_size,
                   const CheckerboardOptions& options) {
  BoardHint hint;
  hint.method = board.method;
  hint.scale = board.scale;
  if (board.corners_px.empty()) return hint;
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (const auto& p : board.corners_px) {
    x0 = std::min(x0, p.x()), y0 = std::min(y0, p.y());
    x1 = std::max(x1, p.x()), y1 = std::max(y1, p.y());
  }
  const double grow = options.hint_margin_squares * board.square_px;
  const cv::Rect r(
      cv::Point(static_cast<int>(std::floor(x0 - grow)), static_cast<int>(std::floor(y0 - grow))),
      cv::Point(static_cast<int>(std::ceil(x1 + grow)) + 1,
                static_cast<int>(std::ceil(y1 + grow)) + 1));
  hint.region = r & cv::Rect(cv::Point(0, 0), image_size);
  return hint;
}

BoardArea::BoardArea(const CheckerboardDetection& board, BoardSize size) : size_(size) {
  if (board.corners_px.size() != static_cast<size_t>(size.cols * size.rows)) return;
  const cv::Mat h = BoardHomography(board, size);
  if (h.empty()) return;
  const cv::Matx33d board_to_image(h);
  if (std::abs(cv::determinant(board_to_image)) < 1e-300) return;
  image_to_board_ = board_to_image.inv();
  // The board's centre is in front of the camera: its pixel maps back with the sign every
  // point of the visible plane has.
  const cv::Vec3d centre =
      board_to_image * cv::Vec3d(0.5 * (size.cols - 1), 0.5 * (size.rows - 1), 1);
  if (std::abs(centre[2]) < 1e-300) return;
  const cv::Vec3d back =
      image_to_board_ * cv::Vec3d(centre[0] / centre[2], centre[1] / centre[2], 1);
  front_sign_ = back[2] > 0 ? 1.0 : -1.0;
  valid_ = std::isfinite(back[2]) && back[2] != 0;
}

bool BoardArea::Contains(const Eigen::Vector2d& px, double margin) const {
  if (!valid_ || !px.allFinite()) return false;
  const cv::Vec3d b = image_to_board_ * cv::Vec3d(px.x(), px.y(), 1);
  if (!(b[2] * front_sign_ > 0)) return false;  // beyond the plane's horizon
  const double c = b[0] / b[2], r = b[1] / b[2];
  const double lo = -1 - margin;
  return c >= lo && r >= lo && c <= size_.cols + margin && r <= size_.rows + margin;
}

bool InsideOutline(const std::vector<Eigen::Vector2d>& outline, const Eigen::Vector2d& px) {
  if (outline.size() < 3) return false;
  std::vector<cv::Point2f> poly;
  for (const auto& p : outline)
    poly.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  return cv::pointPolygonTest(
             poly, cv::Point2f(static_cast<float>(px.x()), static_cast<float>(px.y())), false) >= 0;
}

std::vector<std::optional<CheckerboardDetection>> DetectCheckerboards(
    const cv::Mat& image, const std::vector<BoardSize>& sizes, const CheckerboardOptions& options,
    std::vector<std::vector<BoardAttempt>>* attempts,
    const std::vector<std::optional<BoardHint>>* hints) {
  if (hints && hints->size() != sizes.size())
    throw std::invalid_argument("DetectCheckerboards: one hint (or none) per board size");
  if (attempts) attempts->assign(sizes.size(), {});
  std::vector<size_t> order(sizes.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return sizes[a].cols * sizes[a].rows > sizes[b].cols * sizes[b].rows;
  });
  std::vector<std::optional<CheckerboardDetection>> out(sizes.size());
  cv::Mat mask(image.size(), CV_8U, cv::Scalar(255));
  for (size_t k : order) {
    const BoardHint* hint = hints && (*hints)[k] ? &*(*hints)[k] : nullptr;
    out[k] = DetectCheckerboard(image, sizes[k], options, mask,
                                attempts ? &(*attempts)[k] : nullptr, hint);
    if (!out[k]) continue;
    // Mask the board's hull, grown by one square on each side.
    const auto& c = out[k]->corners_px;
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const auto& p : c) centre += p;
    centre /= static_cast<double>(c.size());
    const int cols = sizes[k].cols, rows = sizes[k].rows;
    const Eigen::Vector2d ends[4] = {c[0], c[cols - 1], c[(rows - 1) * cols + cols - 1],
                                     c[(rows - 1) * cols]};
    std::vector<cv::Point> hull;
    const double grow_x = (c[1] - c[0]).norm() * 1.5;
    for (const auto& e : ends) {
      const Eigen::Vector2d dir = (e - centre).normalized();
      const Eigen::Vector2d p = e + dir * grow_x * std::sqrt(2.0);
      hull.emplace_back(static_cast<int>(p.x()), static_cast<int>(p.y()));
    }
    cv::fillConvexPoly(mask, hull, cv::Scalar(0));
  }
  return out;
}

}  // namespace msmcal::vision

#include "processing/vision/checkerboard.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace msmcal::vision {
namespace {

double MeanAround(const cv::Mat& gray, const Eigen::Vector2d& p, int half) {
  const int x0 = std::clamp(static_cast<int>(std::lround(p.x())) - half, 0, gray.cols - 1);
  const int y0 = std::clamp(static_cast<int>(std::lround(p.y())) - half, 0, gray.rows - 1);
  const int x1 = std::clamp(static_cast<int>(std::lround(p.x())) + half, 0, gray.cols - 1);
  const int y1 = std::clamp(static_cast<int>(std::lround(p.y())) + half, 0, gray.rows - 1);
  return cv::mean(gray(cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1)))[0];
}

}  // namespace

std::string CheckerboardOptions::Validate() const {
  std::ostringstream s;
  if (coarse_max_side_px < 200)
    s << "coarse_max_side_px = " << coarse_max_side_px << " must be >= 200";
  return s.str();
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

std::optional<CheckerboardDetection> DetectCheckerboard(const cv::Mat& image, BoardSize size,
                                                        const CheckerboardOptions& options,
                                                        const cv::Mat& mask) {
  if (const std::string err = options.Validate(); !err.empty())
    throw std::invalid_argument("CheckerboardOptions: " + err);
  if (size.cols < 2 || size.rows < 2)
    throw std::invalid_argument("DetectCheckerboard: board needs >= 2x2 inner corners");
  cv::Mat gray = ToGray8(image);
  if (!mask.empty()) {
    cv::Mat masked(gray.size(), CV_8U, cv::Scalar(128));
    gray.copyTo(masked, mask);
    gray = masked;
  }
  // Coarse search on a ladder of scales (findChessboardCornersSB succeeds or fails somewhat
  // erratically with the square size in pixels), full resolution last.
  const int side = std::max(gray.cols, gray.rows);
  std::vector<double> scales;
  for (double f : {1.0, 0.7, 1.4}) {
    const double s = f * options.coarse_max_side_px / side;
    if (s < 1.0) scales.push_back(s);
  }
  scales.push_back(1.0);
  std::vector<cv::Point2f> found;
  bool ok = false;
  for (double scale : scales) {
    cv::Mat small;
    if (scale < 1.0)
      cv::resize(gray, small, cv::Size(), scale, scale, cv::INTER_AREA);
    else
      small = gray;
    if (!cv::findChessboardCornersSB(small, cv::Size(size.cols, size.rows), found, 0)) continue;
    for (auto& p : found) {
      // Pixel-centre convention: p_full = (p_small + 0.5) / scale - 0.5.
      p.x = static_cast<float>((p.x + 0.5) / scale - 0.5);
      p.y = static_cast<float>((p.y + 0.5) / scale - 0.5);
    }
    ok = true;
    break;
  }
  if (!ok) return std::nullopt;
  // Refinement window from the smallest corner spacing.
  double spacing = 1e9;
  for (int r = 0; r < size.rows; ++r)
    for (int c = 0; c + 1 < size.cols; ++c)
      spacing = std::min<double>(spacing,
                                 cv::norm(found[r * size.cols + c + 1] - found[r * size.cols + c]));
  const int win = std::clamp(static_cast<int>(spacing * 0.3), 2, 15);
  cv::cornerSubPix(gray, found, cv::Size(win, win), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 40, 1e-3));
  std::vector<Eigen::Vector2d> grid;
  grid.reserve(found.size());
  for (const auto& p : found) grid.emplace_back(p.x, p.y);
  CheckerboardDetection det;
  det.corners_px = CanonicalCornerOrder(grid, size, gray);
  det.refine_half_window_px = win;
  return det;
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

std::vector<Eigen::Vector2d> SquaresOutline(const CheckerboardDetection& board, BoardSize size,
                                            double margin) {
  std::vector<cv::Point2f> src, dst;
  for (int r = 0; r < size.rows; ++r)
    for (int c = 0; c < size.cols; ++c) {
      src.emplace_back(static_cast<float>(c), static_cast<float>(r));
      const auto& p = board.corners_px[r * size.cols + c];
      dst.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
  const cv::Mat h = cv::findHomography(src, dst, 0);
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

bool InsideOutline(const std::vector<Eigen::Vector2d>& outline, const Eigen::Vector2d& px) {
  if (outline.size() < 3) return false;
  std::vector<cv::Point2f> poly;
  for (const auto& p : outline)
    poly.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  return cv::pointPolygonTest(
             poly, cv::Point2f(static_cast<float>(px.x()), static_cast<float>(px.y())), false) >= 0;
}

std::vector<std::optional<CheckerboardDetection>> DetectCheckerboards(
    const cv::Mat& image, const std::vector<BoardSize>& sizes, const CheckerboardOptions& options) {
  std::vector<size_t> order(sizes.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return sizes[a].cols * sizes[a].rows > sizes[b].cols * sizes[b].rows;
  });
  std::vector<std::optional<CheckerboardDetection>> out(sizes.size());
  cv::Mat mask(image.size(), CV_8U, cv::Scalar(255));
  for (size_t k : order) {
    out[k] = DetectCheckerboard(image, sizes[k], options, mask);
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

#include "processing/vision/dots.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace msmcal::vision {
namespace {

// Signal of one pixel: mono brightness, or green minus max(blue, red) in BGR.
template <typename T, int kChannels>
inline int Signal(const T* row, int x) {
  if constexpr (kChannels == 1) {
    return row[x];
  } else {
    const T* p = row + 3 * x;
    const int other = std::max<int>(p[0], p[2]);
    return static_cast<int>(p[1]) - other;
  }
}

template <typename T, int kChannels>
inline bool Saturated(const T* row, int x, int full) {
  if constexpr (kChannels == 1) {
    return row[x] >= full;
  } else {
    return row[3 * x + 1] >= full;
  }
}

struct Accumulator {
  double sw = 0, sw2 = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
  int n = 0, saturated = 0;
  double peak = 0;
};

template <typename T, int kChannels>
std::vector<Dot> Detect(const cv::Mat& image, const cv::Mat& original, const DotOptions& o,
                        DotRejections* rej) {
  const int full = sizeof(T) == 1 ? 255 : 65535;
  const int threshold = std::max(1, static_cast<int>(std::lround(o.threshold_fraction * full)));
  const int w = image.cols, h = image.rows;
  cv::Mat1b visited(h, w, uchar{0});
  std::vector<std::pair<int, int>> stack;
  std::vector<Dot> dots;
  DotRejections local;
  for (int y = 0; y < h; ++y) {
    const T* row = image.ptr<T>(y);
    const uchar* vrow = visited.ptr<uchar>(y);
    for (int x = 0; x < w; ++x) {
      if (Signal<T, kChannels>(row, x) < threshold || vrow[x]) continue;
      // Flood fill (8-connected) from (x, y).
      Accumulator acc;
      stack.clear();
      stack.emplace_back(x, y);
      visited(y, x) = 1;
      while (!stack.empty()) {
        auto [cx, cy] = stack.back();
        stack.pop_back();
        const T* r = image.ptr<T>(cy);
        // Weight = signal (the top-hat has already removed the background in mono images).
        const double s = Signal<T, kChannels>(r, cx);
        ++acc.n;
        if (Saturated<T, kChannels>(original.ptr<T>(cy), cx, full)) ++acc.saturated;
        acc.peak = std::max(acc.peak, s);
        acc.sw += s;
        acc.sw2 += s * s;
        acc.sx += s * cx;
        acc.sy += s * cy;
        acc.sxx += s * cx * cx;
        acc.sxy += s * cx * cy;
        acc.syy += s * cy * cy;
        if (acc.n > o.max_pixels + 1) continue;  // stop growing; rejected below anyway
        for (int dy = -1; dy <= 1; ++dy) {
          const int ny = cy + dy;
          if (ny < 0 || ny >= h) continue;
          const T* nr = image.ptr<T>(ny);
          uchar* nv = visited.ptr<uchar>(ny);
          for (int dx = -1; dx <= 1; ++dx) {
            const int nx = cx + dx;
            if (nx < 0 || nx >= w || nv[nx]) continue;
            if (Signal<T, kChannels>(nr, nx) < threshold) continue;
            nv[nx] = 1;
            stack.emplace_back(nx, ny);
          }
        }
      }
      if (acc.n < o.min_pixels) {
        ++local.too_small;
        continue;
      }
      if (acc.n > o.max_pixels) {
        ++local.too_large;
        continue;
      }
      if (acc.saturated > o.max_saturated_fraction * acc.n) {
        ++local.saturated;
        continue;
      }
      Dot dot;
      dot.px = Eigen::Vector2d(acc.sx / acc.sw, acc.sy / acc.sw);
      Eigen::Matrix2d scatter;
      scatter(0, 0) = acc.sxx / acc.sw - dot.px.x() * dot.px.x();
      scatter(0, 1) = acc.sxy / acc.sw - dot.px.x() * dot.px.y();
      scatter(1, 1) = acc.syy / acc.sw - dot.px.y() * dot.px.y();
      scatter(1, 0) = scatter(0, 1);
      // Pixel quantisation floor (1/12 px^2) keeps one-row blobs from a singular covariance.
      scatter += Eigen::Matrix2d::Identity() / 12.0;
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(scatter);
      const double l0 = std::max(es.eigenvalues()(0), 1e-12);
      if (std::sqrt(es.eigenvalues()(1) / l0) > o.max_elongation) {
        ++local.elongated;
        continue;
      }
      // Effective number of samples of a weighted mean.
      const double n_eff = acc.sw * acc.sw / acc.sw2;
      dot.cov_px2 = scatter / n_eff;
      dot.num_pixels = acc.n;
      dot.peak = acc.peak;
      dots.push_back(dot);
    }
  }
  if (rej) *rej = local;
  return dots;
}

}  // namespace

std::string DotOptions::Validate() const {
  std::ostringstream s;
  if (!(threshold_fraction > 0 && threshold_fraction < 1))
    s << "threshold_fraction = " << threshold_fraction << " must be in (0, 1)";
  else if (min_pixels < 1)
    s << "min_pixels = " << min_pixels << " must be >= 1";
  else if (max_pixels < min_pixels)
    s << "max_pixels = " << max_pixels << " must be >= min_pixels (" << min_pixels << ")";
  else if (!(max_elongation >= 1))
    s << "max_elongation = " << max_elongation << " must be >= 1";
  else if (background_kernel_px < 0 || (background_kernel_px > 0 && background_kernel_px % 2 == 0))
    s << "background_kernel_px = " << background_kernel_px << " must be 0 or odd and positive";
  else if (!(max_saturated_fraction >= 0 && max_saturated_fraction <= 1))
    s << "max_saturated_fraction = " << max_saturated_fraction << " must be in [0, 1]";
  return s.str();
}

std::vector<Dot> DetectDots(const cv::Mat& image, const DotOptions& options,
                            DotRejections* rejections) {
  if (const std::string err = options.Validate(); !err.empty())
    throw std::invalid_argument("DotOptions: " + err);
  // The top-hat goes into its own buffer: the caller's image is const and is read below for
  // saturation.
  cv::Mat signal;
  if (image.channels() != 1 || options.background_kernel_px <= 0) signal = image;
  if (image.channels() == 1 && options.background_kernel_px > 0) {
    // Top-hat: bright structures smaller than the kernel (dots) over the local background
    // (board squares).
    const cv::Mat kernel = cv::getStructuringElement(
        cv::MORPH_RECT, cv::Size(options.background_kernel_px, options.background_kernel_px));
    cv::morphologyEx(image, signal, cv::MORPH_TOPHAT, kernel);
  }
  switch (image.type()) {
    case CV_8UC1:
      return Detect<uint8_t, 1>(signal, image, options, rejections);
    case CV_8UC3:
      return Detect<uint8_t, 3>(image, image, options, rejections);
    case CV_16UC1:
      return Detect<uint16_t, 1>(signal, image, options, rejections);
    case CV_16UC3:
      return Detect<uint16_t, 3>(image, image, options, rejections);
    default:
      throw std::invalid_argument("DetectDots: unsupported image type " +
                                  std::to_string(image.type()) +
                                  " (expected 8/16-bit, 1 or 3 channels)");
  }
}

std::vector<Dot> DetectDotsOpenCvReference(const cv::Mat& image, const DotOptions& options) {
  const double full = image.depth() == CV_16U ? 65535 : 255;
  cv::Mat signal;
  if (image.channels() == 3) {
    std::vector<cv::Mat> ch;
    cv::split(image, ch);
    cv::Mat other = cv::max(ch[0], ch[2]);
    cv::subtract(ch[1], other, signal);
  } else {
    signal = image;
  }
  cv::Mat mask;
  cv::inRange(signal, cv::Scalar(options.threshold_fraction * full), cv::Scalar(full), mask);
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  std::vector<Dot> dots;
  for (int i = 1; i < n; ++i) {
    const int area = stats.at<int>(i, cv::CC_STAT_AREA);
    if (area < options.min_pixels || area > options.max_pixels) continue;
    Dot d;
    d.px = Eigen::Vector2d(centroids.at<double>(i, 0), centroids.at<double>(i, 1));
    d.num_pixels = area;
    dots.push_back(d);
  }
  return dots;
}

}  // namespace msmcal::vision

#include "processing/vision/dots.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace msmcal::vision {
namespace {

// Signal of one pixel: mono brightness, or the green channel in BGR.
template <typename T, int kChannels>
inline int Signal(const T* row, int x) {
  if constexpr (kChannels == 1) {
    return row[x];
  } else {
    return row[3 * x + 1];
  }
}

// BGR: green minus the larger of blue and red (laser light vs white light).
template <typename T>
inline int GreenExcess(const T* row, int x) {
  const T* p = row + 3 * x;
  return static_cast<int>(p[1]) - std::max<int>(p[0], p[2]);
}

// Per channel: each blob pixel's rise over its local background, the channel's morphological
// opening with the top-hat's kernel (a flat k x k element: what the dot detector itself takes as
// the background); returns the largest green rise minus the larger of the blue and red rises at
// that pixel. On a checkerboard the background is the square under the spot, whatever its tint
// (a ring median mixes dark and light squares and reports the light square's colour instead).
// Without a kernel (kernel_px < 3): the median of a ring around the box (the box grown by its
// own size, at least 3 px).
int RelativeGreenExcess(const cv::Mat& image, const cv::Rect& box, int kernel_px) {
  if (kernel_px >= 3) {
    const int m = kernel_px;
    const cv::Rect win = cv::Rect(box.x - m, box.y - m, box.width + 2 * m, box.height + 2 * m) &
                         cv::Rect(0, 0, image.cols, image.rows);
    const cv::Mat kernel =
        cv::getStructuringElement(cv::MORPH_RECT, cv::Size(kernel_px, kernel_px));
    std::array<cv::Mat1i, 3> rise;
    for (int c = 0; c < 3; ++c) {
      cv::Mat ch, eroded, opened, ch32, opened32;
      cv::extractChannel(image(win), ch, c);
      cv::erode(ch, eroded, kernel);
      cv::dilate(eroded, opened, kernel);
      ch.convertTo(ch32, CV_32S);
      opened.convertTo(opened32, CV_32S);
      rise[c] = ch32 - opened32;
    }
    int best = std::numeric_limits<int>::min();
    const cv::Rect in_win = (box & win) - win.tl();
    for (int y = in_win.y; y < in_win.y + in_win.height; ++y)
      for (int x = in_win.x; x < in_win.x + in_win.width; ++x)
        best = std::max(best, rise[1](y, x) - std::max(rise[0](y, x), rise[2](y, x)));
    return best;
  }
  const int m = std::max(3, std::max(box.width, box.height));
  const cv::Rect outer = cv::Rect(box.x - m, box.y - m, box.width + 2 * m, box.height + 2 * m) &
                         cv::Rect(0, 0, image.cols, image.rows);
  std::array<std::vector<int>, 3> ring;
  std::array<int, 3> top{0, 0, 0};
  for (int y = outer.y; y < outer.y + outer.height; ++y)
    for (int x = outer.x; x < outer.x + outer.width; ++x) {
      const bool inside = box.contains(cv::Point(x, y));
      for (int c = 0; c < 3; ++c) {
        const int v = image.depth() == CV_8U ? image.ptr<uint8_t>(y)[3 * x + c]
                                             : image.ptr<uint16_t>(y)[3 * x + c];
        if (inside)
          top[c] = std::max(top[c], v);
        else
          ring[c].push_back(v);
      }
    }
  if (ring[0].empty()) return std::numeric_limits<int>::min();
  std::array<int, 3> rise{};
  for (int c = 0; c < 3; ++c) {
    std::nth_element(ring[c].begin(), ring[c].begin() + ring[c].size() / 2, ring[c].end());
    rise[c] = top[c] - ring[c][ring[c].size() / 2];
  }
  return rise[1] - std::max(rise[0], rise[2]);
}

template <typename T, int kChannels>
inline bool Saturated(const T* row, int x, int full) {
  if constexpr (kChannels == 1) {
    return row[x] >= full;
  } else {
    return row[3 * x + 1] >= full;
  }
}

// BGR: the pixel's green is clipped, its blue and red are not, and (over a background: a
// non-null `difference_row`) the spot raised its green.
template <typename T>
inline bool GreenClipsAlone(const T* image_row, const T* difference_row, int x, int full) {
  const T* p = image_row + 3 * x;
  return p[1] >= full && p[0] < full && p[2] < full &&
         (difference_row == nullptr || difference_row[3 * x + 1] > 0);
}

struct Accumulator {
  double sw = 0, sw2 = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
  int n = 0, saturated = 0;
  double peak = 0, peak_level = 0;
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // bounding box, inclusive
};

struct FitPixel {
  double x, y, s;
  bool censored;
};

// Least-squares fit of m(p) = b0 + A exp(-q/2), q = (p - c)^T P (p - c), to the signal of the
// pixels of a window; saturated pixels only bound the model from below (their true signal is at
// least what was measured). Levenberg-Marquardt over theta = (cx, cy, A, b0, P00, P01, P11),
// started from the blob (dot->px, dot->peak, dot->scatter_px2). Returns false if it does not
// converge to a usable spot; else sets dot->px, dot->cov_px2 and dot->fitted.
bool FitGaussian(const std::vector<FitPixel>& px, Dot* dot, double* residual_var = nullptr,
                 double* amplitude = nullptr) {
  using Px = FitPixel;
  const Eigen::Matrix2d& scatter = dot->scatter_px2;
  const int n = static_cast<int>(px.size());
  constexpr int kP = 7;
  if (n < 2 * kP) return false;
  using Vec = Eigen::Matrix<double, kP, 1>;
  using Mat = Eigen::Matrix<double, kP, kP>;
  // Start from the blob's scatter, widened: the pixels above threshold are only the spot's core.
  const Eigen::Matrix2d p0 = (1.5 * scatter).inverse();
  Vec th;
  th << dot->px.x(), dot->px.y(), dot->peak, 0.0, p0(0, 0), p0(0, 1), p0(1, 1);
  // Cost at t; with jtj, also J^T J, J^T r and the number of pixels that constrain the fit
  // (all but clipped ones the model exceeds).
  int used = 0;
  auto evaluate = [&](const Vec& t, Mat* jtj, Vec* jtr) {
    double cost = 0;
    if (jtj) used = 0;
    if (jtj) jtj->setZero(), jtr->setZero();
    for (const Px& q : px) {
      const double dx = q.x - t(0), dy = q.y - t(1);
      const double quad = t(4) * dx * dx + 2 * t(5) * dx * dy + t(6) * dy * dy;
      const double g = std::exp(-0.5 * quad);
      const double m = t(3) + t(2) * g;
      double r = m - q.s;
      if (q.censored && r > 0) r = 0;  // the model may exceed a clipped pixel
      if (r == 0 && q.censored) continue;
      cost += r * r;
      if (!jtj) continue;
      ++used;
      const double ag = t(2) * g;
      Vec j;
      j << ag * (t(4) * dx + t(5) * dy), ag * (t(5) * dx + t(6) * dy), g, 1.0, -0.5 * ag * dx * dx,
          -ag * dx * dy, -0.5 * ag * dy * dy;
      jtj->selfadjointView<Eigen::Lower>().rankUpdate(j);
      *jtr += j * r;
    }
    if (jtj) *jtj = jtj->selfadjointView<Eigen::Lower>();
    return cost;
  };
  auto valid = [](const Vec& t) {
    return t(2) > 0 && t(4) > 0 && t(6) > 0 && t(4) * t(6) - t(5) * t(5) > 0 && t.allFinite();
  };
  Mat jtj;
  Vec jtr;
  double cost = evaluate(th, &jtj, &jtr);
  double lambda = 1e-3;
  bool converged = false;
  for (int it = 0; it < 50; ++it) {
    Mat a = jtj;
    a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
    const Vec step = a.ldlt().solve(-jtr);
    const Vec cand = th + step;
    if (!valid(cand)) {
      lambda *= 10;
      if (lambda > 1e8) break;
      continue;
    }
    const double c2 = evaluate(cand, nullptr, nullptr);
    if (c2 <= cost) {
      const double rel = (cost - c2) / std::max(cost, 1e-300);
      th = cand;
      cost = evaluate(th, &jtj, &jtr);
      lambda = std::max(lambda * 0.3, 1e-9);
      if (rel < 1e-10 || step.head<2>().norm() < 1e-6) {
        converged = true;
        break;
      }
    } else {
      lambda *= 10;
      if (lambda > 1e8) break;
    }
  }
  if (!converged || !valid(th)) return false;
  // Covariance of the centre: residual variance x (J^T J)^-1 over the pixels that constrain it
  // (jtj, jtr and used are those of th: evaluated when it was accepted).
  if (used <= kP) return false;
  const double s2 = cost / (used - kP);
  const Eigen::LDLT<Mat> ldlt(jtj);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
  const Mat inv = ldlt.solve(Mat::Identity());
  const Eigen::Matrix2d c = s2 * inv.topLeftCorner<2, 2>();
  if (!c.allFinite() || !(c(0, 0) > 0) || !(c.determinant() > 0)) return false;
  dot->px = th.head<2>();
  dot->cov_px2 = 0.5 * (c + c.transpose());
  dot->fitted = true;
  if (residual_var) *residual_var = s2;
  if (amplitude) *amplitude = th(2);
  return true;
}

// The spot fitted through a power-law response (RefineDotOnBackground's contract): levels in
// units of full scale, model m = (b^(1/gamma) + A g(p))^gamma with g the Gaussian of centre c and
// precision P; theta = (cx, cy, A, P00, P01, P11, gamma). Censored pixels bound from below.
// Levenberg-Marquardt with a central-difference Jacobian, started from `dot` (a plain fit).
// Returns the residual variance (< 0: no usable fit) and sets dot->px, cov_px2, response_gamma.
struct ResponsePixel {
  double x, y, level, background;
  bool censored;
};
double FitThroughResponse(const std::vector<ResponsePixel>& px, double amplitude, Dot* dot,
                          double* gamma_sigma) {
  constexpr int kP = 7;
  const int n = static_cast<int>(px.size());
  if (n < 2 * kP) return -1;
  using Vec = Eigen::Matrix<double, kP, 1>;
  using Mat = Eigen::Matrix<double, kP, kP>;
  const Eigen::Matrix2d p0 = (1.5 * dot->scatter_px2).inverse();
  Vec th;
  th << dot->px.x(), dot->px.y(), std::max(amplitude, 1e-3), p0(0, 0), p0(0, 1), p0(1, 1), 1.0;
  auto model = [&](const Vec& t, const ResponsePixel& q) {
    const double dx = q.x - t(0), dy = q.y - t(1);
    const double quad = t(3) * dx * dx + 2 * t(4) * dx * dy + t(5) * dy * dy;
    const double b = std::max(q.background, 1e-4);
    return std::pow(std::pow(b, 1.0 / t(6)) + t(2) * std::exp(-0.5 * quad), t(6));
  };
  auto valid = [](const Vec& t) {
    return t(2) > 0 && t(3) > 0 && t(5) > 0 && t(3) * t(5) - t(4) * t(4) > 0 && t(6) > 0.2 &&
           t(6) < 5 && t.allFinite();
  };
  int used = 0;
  auto evaluate = [&](const Vec& t, Mat* jtj, Vec* jtr) {
    double cost = 0;
    if (jtj) jtj->setZero(), jtr->setZero(), used = 0;
    for (const ResponsePixel& q : px) {
      const double m = model(t, q);
      double r = m - q.level;
      if (q.censored && r >= 0) continue;  // the model may exceed a clipped pixel
      cost += r * r;
      if (!jtj) continue;
      ++used;
      Vec j;
      for (int k = 0; k < kP; ++k) {
        const double h = 1e-6 * std::max(1.0, std::abs(t(k)));
        Vec a = t, b = t;
        a(k) += h, b(k) -= h;
        j(k) = (model(a, q) - model(b, q)) / (2 * h);
      }
      *jtj += j * j.transpose();
      *jtr += j * r;
    }
    return cost;
  };
  Mat jtj;
  Vec jtr;
  double cost = evaluate(th, &jtj, &jtr);
  double lambda = 1e-3;
  bool converged = false;
  for (int it = 0; it < 60; ++it) {
    Mat a = jtj;
    a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
    const Vec cand = th + a.ldlt().solve(-jtr);
    if (!valid(cand)) {
      if ((lambda *= 10) > 1e8) break;
      continue;
    }
    const double c2 = evaluate(cand, nullptr, nullptr);
    if (c2 <= cost) {
      const double rel = (cost - c2) / std::max(cost, 1e-300);
      const double moved = (cand - th).head<2>().norm();
      th = cand;
      cost = evaluate(th, &jtj, &jtr);
      lambda = std::max(lambda * 0.3, 1e-9);
      if (rel < 1e-10 || moved < 1e-6) {
        converged = true;
        break;
      }
    } else if ((lambda *= 10) > 1e8) {
      break;
    }
  }
  if (!converged || !valid(th) || used <= kP) return -1;
  const double s2 = cost / (used - kP);
  const Eigen::LDLT<Mat> ldlt(jtj);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return -1;
  const Mat inv = ldlt.solve(Mat::Identity());
  const Eigen::Matrix2d c = s2 * inv.topLeftCorner<2, 2>();
  if (!c.allFinite() || !(c(0, 0) > 0) || !(c.determinant() > 0) || !(inv(6, 6) > 0)) return -1;
  dot->px = th.head<2>();
  dot->cov_px2 = 0.5 * (c + c.transpose());
  dot->response_gamma = th(6);
  *gamma_sigma = std::sqrt(s2 * inv(6, 6));
  return s2;
}

// The pixels of `window` of a one-channel signal image for FitGaussian; saturation is read
// from `original` (the image before the top-hat).
template <typename T>
std::vector<FitPixel> WindowPixels(const cv::Mat& signal_image, const cv::Mat& original,
                                   const cv::Rect& window, double full, int skip_parity) {
  std::vector<FitPixel> px;
  px.reserve(window.area());
  for (int y = window.y; y < window.y + window.height; ++y) {
    const T* r = signal_image.ptr<T>(y);
    const T* o = original.ptr<T>(y);
    for (int x = window.x; x < window.x + window.width; ++x)
      if ((x + y) % 2 != skip_parity)  // an interpolated green (InterpolatedGreenParity)
        px.push_back({static_cast<double>(x), static_cast<double>(y), static_cast<double>(r[x]),
                      o[x] >= full});  // `full`: the blob's plateau level (Dot::plateau_level)
  }
  return px;
}

// The level at which a blob's pixels are clipped: full scale, unless the blob's brightest pixels
// in `original` form a flat top (the blob's maximum at least 20 % of full scale), at full scale
// or below it; then the top minus a tolerance that comes from the data:
// - a clean flat top (at least 4 pixels within 1 % of the maximum, no dip inside their convex
//   hull; an unclipped sampled Gaussian of sigma < 5 px has 1-2 there): 1 %;
// - a rippled one (compression such as JPEG, a camera's own filtering after the clip): twice the
//   deepest dip inside that hull, or, where the ripple leaves fewer than 4 pixels within 1 % but
//   at least 4 within `max_tolerance`, `max_tolerance` (DotOptions::plateau_tolerance_fraction).
template <typename T>
double PlateauLevel(const cv::Mat& original, const cv::Rect& box, int full, double max_tolerance) {
  double top = 0;
  for (int y = box.y; y < box.y + box.height; ++y) {
    const T* o = original.ptr<T>(y);
    for (int x = box.x; x < box.x + box.width; ++x) top = std::max<double>(top, o[x]);
  }
  if (top < 0.2 * full) return full;
  const double base = std::max(0.01 * top, 2.0 * full / 255.0);
  const double widest = std::max(base, max_tolerance * top);
  std::vector<cv::Point> flat;
  int near_top = 0;
  for (int y = box.y; y < box.y + box.height; ++y) {
    const T* o = original.ptr<T>(y);
    for (int x = box.x; x < box.x + box.width; ++x) {
      if (o[x] >= top - base) flat.emplace_back(x, y);
      near_top += o[x] >= top - widest;
    }
  }
  if (flat.size() < 4) return near_top >= 4 ? top - widest : full;
  std::vector<cv::Point> hull;
  cv::convexHull(flat, hull);
  const cv::Rect hull_box = cv::boundingRect(hull) & box;
  double dip = 0;
  for (int y = hull_box.y; y < hull_box.y + hull_box.height; ++y) {
    const T* o = original.ptr<T>(y);
    for (int x = hull_box.x; x < hull_box.x + hull_box.width; ++x)
      if (o[x] < top - base &&
          cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(x), static_cast<float>(y)),
                               false) > 0)
        dip = std::max(dip, top - o[x]);
  }
  return top - std::clamp(2.0 * dip, base, widest);
}

// Blobs of the one-channel `image` (signal) seeded and bounded by `candidates`; saturation is
// read from `original`.
template <typename T>
std::vector<Dot> Detect(const cv::Mat& image, const cv::Mat& original, cv::Mat1b& candidates,
                        const DotOptions& o, int skip_parity, DotRejections* rej,
                        std::vector<DotCandidate>* seen) {
  const int full = sizeof(T) == 1 ? 255 : 65535;
  const int w = image.cols, h = image.rows;
  std::vector<std::pair<int, int>> stack;
  std::vector<Dot> dots;
  DotRejections local;
  for (int y = 0; y < h; ++y) {
    const uchar* crow = candidates.ptr<uchar>(y);
    for (int x = 0; x < w; ++x) {
      // Skip runs of non-candidates eight at a time (almost the whole frame).
      while (x + 8 <= w) {
        uint64_t word;
        std::memcpy(&word, crow + x, sizeof(word));
        if (word != 0) break;
        x += 8;
      }
      if (x >= w) break;
      if (!crow[x]) continue;
      // Flood fill (8-connected) from (x, y); a pixel leaves `candidates` when it is reached.
      Accumulator acc;
      stack.clear();
      stack.emplace_back(x, y);
      candidates(y, x) = 0;
      while (!stack.empty()) {
        auto [cx, cy] = stack.back();
        stack.pop_back();
        const T* r = image.ptr<T>(cy);
        // Weight = signal (the top-hat has already removed the background in mono images).
        const double s = r[cx];
        ++acc.n;
        // Past max_pixels + 1 the blob is refused anyway: keep flooding (so that no fragment of
        // it is scanned again as a blob of its own) but stop accumulating.
        if (acc.n > o.max_pixels + 1) {
          acc.x0 = std::min(acc.x0, cx), acc.x1 = std::max(acc.x1, cx);
          acc.y0 = std::min(acc.y0, cy), acc.y1 = std::max(acc.y1, cy);
        } else {
          if (original.ptr<T>(cy)[cx] >= full) ++acc.saturated;
          if (s > acc.peak || acc.n == 1) {
            acc.peak = s;
            acc.peak_level = original.ptr<T>(cy)[cx];
          }
          acc.sw += s;
          acc.sw2 += s * s;
          acc.sx += s * cx;
          acc.sy += s * cy;
          acc.sxx += s * cx * cx;
          acc.sxy += s * cx * cy;
          acc.syy += s * cy * cy;
          if (acc.n == 1) acc.x0 = acc.x1 = cx, acc.y0 = acc.y1 = cy;
          acc.x0 = std::min(acc.x0, cx), acc.x1 = std::max(acc.x1, cx);
          acc.y0 = std::min(acc.y0, cy), acc.y1 = std::max(acc.y1, cy);
        }
        for (int dy = -1; dy <= 1; ++dy) {
          const int ny = cy + dy;
          if (ny < 0 || ny >= h) continue;
          uchar* nc = candidates.ptr<uchar>(ny);
          for (int dx = -1; dx <= 1; ++dx) {
            const int nx = cx + dx;
            if (nx < 0 || nx >= w || !nc[nx]) continue;
            nc[nx] = 0;
            stack.emplace_back(nx, ny);
          }
        }
      }
      DotCandidate cand;
      cand.box = cv::Rect(acc.x0, acc.y0, acc.x1 - acc.x0 + 1, acc.y1 - acc.y0 + 1);
      cand.centroid_px = Eigen::Vector2d(acc.sx / acc.sw, acc.sy / acc.sw);
      cand.num_pixels = acc.n;
      cand.peak = acc.peak;
      cand.saturated_pixels = acc.saturated;
      auto refuse = [&](int* counter, std::string why) {
        ++*counter;
        if (!seen) return;
        cand.reason = std::move(why);
        seen->push_back(cand);
      };
      if (acc.n < o.min_pixels) {
        refuse(&local.too_small, "too small: " + std::to_string(acc.n) + " px < dots.min_pixels " +
                                     std::to_string(o.min_pixels));
        continue;
      }
      if (acc.n > o.max_pixels) {
        refuse(&local.too_large, "too large: > dots.max_pixels " + std::to_string(o.max_pixels));
        continue;
      }
      if (acc.saturated > o.max_saturated_fraction * acc.n) {
        refuse(&local.saturated, "saturated: " + std::to_string(acc.saturated) + " of " +
                                     std::to_string(acc.n) + " px > dots.max_saturated_fraction");
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
      cand.elongation = std::sqrt(es.eigenvalues()(1) / l0);
      if (cand.elongation > o.max_elongation) {
        std::ostringstream why;
        why << "elongated: " << cand.elongation << " > dots.max_elongation " << o.max_elongation;
        refuse(&local.elongated, why.str());
        continue;
      }
      // Effective number of samples of a weighted mean.
      const double n_eff = acc.sw * acc.sw / acc.sw2;
      dot.cov_px2 = scatter / n_eff;
      dot.num_pixels = acc.n;
      dot.peak = acc.peak;
      dot.peak_level = acc.peak_level;
      dot.saturated_pixels = acc.saturated;
      dot.scatter_px2 = scatter;
      dot.centroid_px = dot.px;
      dot.blob_box = cv::Rect(acc.x0, acc.y0, acc.x1 - acc.x0 + 1, acc.y1 - acc.y0 + 1);
      dot.plateau_level =
          PlateauLevel<T>(original, dot.blob_box, full, o.plateau_tolerance_fraction);
      if (o.centre == DotCentre::kGaussianFit) {
        Dot fit = dot;
        if (FitGaussian(WindowPixels<T>(image, original, DotFitWindow(dot, image.size(), o),
                                        dot.plateau_level, skip_parity),
                        &fit) &&
            (fit.px - dot.px).norm() <= o.max_fit_shift_px)
          dot = fit;
        else
          ++local.fit_fallbacks;
      }
      if (seen) {
        cand.kept = true;
        cand.reason = dot.fitted ? "kept (Gaussian fit)" : "kept (weighted centroid)";
        seen->push_back(cand);
      }
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
  else if (!(plateau_tolerance_fraction >= 0 && plateau_tolerance_fraction <= 0.3))
    s << "plateau_tolerance_fraction = " << plateau_tolerance_fraction << " must be in [0, 0.3]";
  else if (fit_margin_px < 0 || fit_margin_px > 50)
    s << "fit_margin_px = " << fit_margin_px << " must be in [0, 50]";
  else if (!(max_fit_shift_px > 0))
    s << "max_fit_shift_px = " << max_fit_shift_px << " must be > 0";
  else if (!(min_green_excess_fraction >= 0 && min_green_excess_fraction < 1))
    s << "min_green_excess_fraction = " << min_green_excess_fraction << " must be in [0, 1)";
  else if (background_mask_margin_px < 0 || background_mask_margin_px > 50)
    s << "background_mask_margin_px = " << background_mask_margin_px << " must be in [0, 50]";
  return s.str();
}

namespace {

// DetectDots and DetectDotsOverBackground: `background` empty for the top-hat, else the signal
// is image - background (and the greenness is read from that difference).
std::vector<Dot> DetectDotsImpl(const cv::Mat& image, const cv::Mat& background,
                                const cv::Mat& given_difference, const DotOptions& options,
                                DotRejections* rejections,
                                std::vector<DotCandidate>* candidates_out) {
  if (const std::string err = options.Validate(); !err.empty())
    throw std::invalid_argument("DotOptions: " + err);
  if (image.type() != CV_8UC1 && image.type() != CV_8UC3 && image.type() != CV_16UC1 &&
      image.type() != CV_16UC3)
    throw std::invalid_argument("DetectDots: unsupported image type " +
                                std::to_string(image.type()) +
                                " (expected 8/16-bit, 1 or 3 channels)");
  if (!background.empty() &&
      (background.size() != image.size() || background.type() != image.type()))
    throw std::invalid_argument(
        "DetectDotsOverBackground: the background differs from the image in size or type");
  // Scratch images per thread, reused from call to call: a fresh 10 MP buffer costs more in page
  // faults than the filter that fills it.
  thread_local cv::Mat eroded, opened, top_hat, difference, difference_green;
  thread_local cv::Mat1b candidates;
  const int full = image.depth() == CV_16U ? 65535 : 255;
  const int threshold =
      std::max(1, static_cast<int>(std::lround(options.threshold_fraction * full)));
  // BGR: the green channel is the signal (see the header); greenness is checked per blob.
  thread_local cv::Mat green;
  const bool bgr = image.channels() == 3;
  cv::Mat mono = image;
  if (bgr) {
    cv::extractChannel(image, green, 1);
    mono = green;
  }
  const int skip_parity = bgr && options.native_green_only ? InterpolatedGreenParity(image) : -1;
  // The top-hat goes into its own buffer: the caller's image is const and is read below for
  // saturation.
  cv::Mat signal = mono;
  if (!background.empty()) {
    if (given_difference.empty())
      cv::subtract(image, background, difference);  // saturating: 0 where the image is darker
    else
      difference = given_difference;
    if (bgr) {
      cv::extractChannel(difference, difference_green, 1);
      signal = difference_green;
    } else {
      signal = difference;
    }
  } else if (options.background_kernel_px > 0) {
    // Top-hat: bright structures smaller than the kernel (dots) over the local background
    // (board squares).
    const cv::Mat kernel = cv::getStructuringElement(
        cv::MORPH_RECT, cv::Size(options.background_kernel_px, options.background_kernel_px));
    cv::erode(mono, eroded, kernel);
    cv::dilate(eroded, opened, kernel);
    cv::subtract(mono, opened, top_hat);
    signal = top_hat;
  }
  // Pixels at or above the threshold: the flood fill's seeds and extent.
  cv::compare(signal, threshold, candidates, cv::CMP_GE);
  // A spot that clips on a light square shows no more than that square's headroom (full scale
  // minus its level), which can be below the threshold: saturated pixels count where their
  // signal reaches half of it (flat areas that clip in the background too show no signal).
  {
    thread_local cv::Mat1b clipped, rising;
    cv::compare(mono, full, clipped, cv::CMP_GE);
    if (cv::countNonZero(clipped) > 0) {
      cv::compare(signal, std::max(1, threshold / 2), rising, cv::CMP_GE);
      cv::bitwise_and(clipped, rising, clipped);
      cv::bitwise_or(candidates, clipped, candidates);
    }
  }
  DotRejections local;
  std::vector<Dot> dots =
      mono.depth() == CV_8U
          ? Detect<uint8_t>(signal, mono, candidates, options, skip_parity, &local, candidates_out)
          : Detect<uint16_t>(signal, mono, candidates, options, skip_parity, &local,
                             candidates_out);
  if (bgr) {
    // Over a background, the difference says what the spot added: laser light adds green.
    const cv::Mat& colour = background.empty() ? image : difference;
    const int min_excess = static_cast<int>(std::lround(options.min_green_excess_fraction * full));
    std::vector<Dot> green_dots;
    for (const Dot& d : dots) {
      int best = std::numeric_limits<int>::min();
      for (int y = d.blob_box.y; y < d.blob_box.y + d.blob_box.height; ++y)
        for (int x = d.blob_box.x; x < d.blob_box.x + d.blob_box.width; ++x)
          best = std::max(best, colour.depth() == CV_8U ? GreenExcess(colour.ptr<uint8_t>(y), x)
                                                        : GreenExcess(colour.ptr<uint16_t>(y), x));
      // Relative to the surroundings: a green spot on a light (white or tinted) square where
      // blue or red is saturated too raises green alone (the absolute excess is ~0 there).
      if (best < min_excess && background.empty())
        best = std::max(best, RelativeGreenExcess(image, d.blob_box, options.background_kernel_px));
      // Where the image's green clips and blue and red do not, the green rise is only a lower
      // bound of what the spot added (a light square's headroom): green light that clipped the
      // channel it is seen in.
      if (best < min_excess && d.saturated_pixels > 0)
        for (int y = d.blob_box.y; y < d.blob_box.y + d.blob_box.height && best < min_excess; ++y)
          for (int x = d.blob_box.x; x < d.blob_box.x + d.blob_box.width; ++x) {
            const bool clipped_green_only =
                image.depth() == CV_8U
                    ? GreenClipsAlone(image.ptr<uint8_t>(y),
                                      background.empty() ? nullptr : difference.ptr<uint8_t>(y), x,
                                      full)
                    : GreenClipsAlone(image.ptr<uint16_t>(y),
                                      background.empty() ? nullptr : difference.ptr<uint16_t>(y), x,
                                      full);
            if (clipped_green_only) {
              best = min_excess;
              break;
            }
          }
      if (best >= min_excess) {
        green_dots.push_back(d);
      } else {
        ++local.not_green;
        if (candidates_out)
          for (auto& c : *candidates_out)
            if (c.kept && c.box == d.blob_box) {
              c.kept = false;
              c.reason = "not green: green - max(blue, red) peaks at " + std::to_string(best) +
                         " < dots.min_green_excess_fraction of full scale";
            }
      }
    }
    dots = std::move(green_dots);
  }
  if (rejections) *rejections = local;
  return dots;
}

}  // namespace

bool StaticBackground::Add(const cv::Mat& image) {
  if (lo_.empty()) {
    lo_ = image.clone();
    lo2_ = cv::Mat(image.size(), image.type(),
                   cv::Scalar::all(image.depth() == CV_16U ? 65535.0 : 255.0));
    count_ = 1;
    return true;
  }
  if (image.size() != lo_.size() || image.type() != lo_.type()) return false;
  cv::Mat hi;
  cv::max(lo_, image, hi);
  cv::min(lo2_, hi, lo2_);
  cv::min(lo_, image, lo_);
  ++count_;
  return true;
}

cv::Mat StaticBackground::Without(const cv::Mat& image) const {
  if (count_ < 2 || image.size() != lo_.size() || image.type() != lo_.type())
    throw std::invalid_argument(
        "StaticBackground::Without: needs 2 images of the image's size and type");
  cv::Mat background = lo_.clone(), holds_min;
  cv::compare(image, lo_, holds_min, cv::CMP_LE);
  lo2_.copyTo(background, holds_min);
  return background;
}

std::vector<Dot> DetectDots(const cv::Mat& image, const DotOptions& options,
                            DotRejections* rejections, std::vector<DotCandidate>* candidates_out) {
  return DetectDotsImpl(image, cv::Mat(), cv::Mat(), options, rejections, candidates_out);
}

std::vector<Dot> DetectDotsOverBackground(const cv::Mat& image, const cv::Mat& background,
                                          const DotOptions& options, DotRejections* rejections,
                                          std::vector<DotCandidate>* candidates) {
  if (background.empty()) throw std::invalid_argument("DetectDotsOverBackground: empty background");
  return DetectDotsImpl(image, background, cv::Mat(), options, rejections, candidates);
}

namespace {

// Robust sigma (1.4826 MAD) of image - background, signed, in the green channel of a BGR image,
// over every pixel of a sample of rows: the noise of a difference of two exposures of a static
// scene (the spots are too few pixels to move the median).
double SignedDifferenceSigma(const cv::Mat& image, const cv::Mat& background) {
  const int ch = image.channels();
  const int c = ch == 3 ? 1 : 0;
  const int row_step = std::max(1, image.rows / 300);
  std::vector<float> d;
  d.reserve(static_cast<size_t>(image.cols) * (image.rows / row_step + 1));
  for (int y = 0; y < image.rows; y += row_step) {
    for (int x = 0; x < image.cols; ++x) {
      const int k = x * ch + c;
      d.push_back(image.depth() == CV_8U
                      ? float(image.ptr<uint8_t>(y)[k]) - float(background.ptr<uint8_t>(y)[k])
                      : float(image.ptr<uint16_t>(y)[k]) - float(background.ptr<uint16_t>(y)[k]));
    }
  }
  if (d.empty()) return 0;
  auto mid = d.begin() + d.size() / 2;
  std::nth_element(d.begin(), mid, d.end());
  const float median = *mid;
  for (float& v : d) v = std::abs(v - median);
  std::nth_element(d.begin(), mid, d.end());
  return 1.4826 * *mid;
}

}  // namespace

std::vector<Dot> DetectDotsOverBackgroundAdaptive(const cv::Mat& image, const cv::Mat& background,
                                                  double square_px, const DotOptions& base,
                                                  DotOptions* used, DotRejections* rejections,
                                                  std::vector<DotCandidate>* candidates) {
  if (background.empty() || background.size() != image.size() || background.type() != image.type())
    throw std::invalid_argument(
        "DetectDotsOverBackground: the background differs from the image in size or type");
  cv::Mat difference;
  cv::subtract(image, background, difference);
  DotOptions options = AdaptiveDotOptions(difference, square_px, base);
  // The clipped difference is zero wherever the image is below its background (half the static
  // scene), so its pixel-to-pixel noise reads low: the threshold comes from the signed
  // difference's robust spread instead (same rule: 8 sigmas, between 2 % of full scale and
  // base's).
  const double full = image.depth() == CV_16U ? 65535.0 : 255.0;
  options.threshold_fraction =
      std::clamp(8.0 * std::max(SignedDifferenceSigma(image, background), 0.5) / full,
                 options.threshold_fraction, base.threshold_fraction);
  if (used) *used = options;
  return DetectDotsImpl(image, background, difference, options, rejections, candidates);
}

namespace {

// Median of a sample of `m`'s values (every pixel of every `row_step`-th row), as a double.
double SampledMedian(const cv::Mat& m, int row_step, bool abs_horizontal_difference) {
  std::vector<float> v;
  v.reserve(static_cast<size_t>(m.cols) * (m.rows / row_step + 1));
  for (int y = 0; y < m.rows; y += row_step) {
    if (m.depth() == CV_8U) {
      const uint8_t* r = m.ptr<uint8_t>(y);
      for (int x = 0; x + 1 < m.cols; ++x)
        v.push_back(abs_horizontal_difference ? std::abs(int{r[x + 1]} - int{r[x]}) : r[x]);
    } else {
      const uint16_t* r = m.ptr<uint16_t>(y);
      for (int x = 0; x + 1 < m.cols; ++x)
        v.push_back(abs_horizontal_difference ? std::abs(int{r[x + 1]} - int{r[x]}) : r[x]);
    }
  }
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

DotOptions AdaptiveDotOptions(const cv::Mat& image, double square_px, const DotOptions& base) {
  if (image.type() != CV_8UC1 && image.type() != CV_8UC3 && image.type() != CV_16UC1 &&
      image.type() != CV_16UC3)
    throw std::invalid_argument("AdaptiveDotOptions: unsupported image type " +
                                std::to_string(image.type()));
  DotOptions o = base;
  int k = static_cast<int>(std::floor(0.8 * std::max(square_px, 0.0)));
  if (k % 2 == 0) --k;
  k = std::clamp(k, 5, 61);
  o.background_kernel_px = k;
  cv::Mat mono = image;
  if (image.channels() == 3) cv::extractChannel(image, mono, 1);
  const double full = image.depth() == CV_16U ? 65535.0 : 255.0;
  const int row_step = std::max(1, mono.rows / 300);
  // Pixel-to-pixel noise: the median absolute horizontal difference (edges are too few to move
  // it), 1.4826 / sqrt(2) of it is the noise sigma.
  const double sigma = 1.4826 / std::sqrt(2.0) * SampledMedian(mono, row_step, true);
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k));
  cv::Mat eroded, opened, top_hat;
  cv::erode(mono, eroded, kernel);
  cv::dilate(eroded, opened, kernel);
  cv::subtract(mono, opened, top_hat);
  const double floor_level = SampledMedian(top_hat, row_step, false);
  o.threshold_fraction =
      std::clamp((floor_level + 8.0 * std::max(sigma, 0.5)) / full, 0.02, base.threshold_fraction);
  o.min_pixels = std::min(base.min_pixels, 4);
  o.max_pixels = std::max(base.max_pixels, k * k);
  o.fit_margin_px = std::clamp(std::max(base.fit_margin_px, k / 4), 0, 50);
  return o;
}

cv::Rect DotFitWindow(const Dot& dot, const cv::Size& image_size, const DotOptions& options) {
  const int m = options.fit_margin_px;
  const cv::Rect grown(dot.blob_box.x - m, dot.blob_box.y - m, dot.blob_box.width + 2 * m,
                       dot.blob_box.height + 2 * m);
  return grown & cv::Rect(0, 0, image_size.width, image_size.height);
}

namespace {

template <typename T, int kChannels>
void ReadSignalT(const cv::Mat& image, const cv::Rect& window, cv::Mat1f* signal,
                 cv::Mat1b* saturated, const cv::Mat1b* mask_out, cv::Mat1f* level) {
  const int full = sizeof(T) == 1 ? 255 : 65535;
  for (int y = 0; y < window.height; ++y) {
    const T* r = image.ptr<T>(window.y + y);
    float* s = signal->ptr<float>(y);
    uchar* sat = saturated ? saturated->ptr<uchar>(y) : nullptr;
    float* lv = level ? level->ptr<float>(y) : nullptr;
    const uchar* m = mask_out ? mask_out->ptr<uchar>(y) : nullptr;
    for (int x = 0; x < window.width; ++x) {
      if (m && m[x]) continue;
      s[x] = static_cast<float>(Signal<T, kChannels>(r, window.x + x));
      if (sat) sat[x] = Saturated<T, kChannels>(r, window.x + x, full) ? 1 : 0;
      if (lv) lv[x] = static_cast<float>(r[kChannels * (window.x + x) + (kChannels == 3 ? 1 : 0)]);
    }
  }
}

void ReadSignal(const cv::Mat& image, const cv::Rect& window, cv::Mat1f* signal,
                cv::Mat1b* saturated, const cv::Mat1b* mask_out, cv::Mat1f* level = nullptr) {
  switch (image.type()) {
    case CV_8UC1:
      return ReadSignalT<uint8_t, 1>(image, window, signal, saturated, mask_out, level);
    case CV_8UC3:
      return ReadSignalT<uint8_t, 3>(image, window, signal, saturated, mask_out, level);
    case CV_16UC1:
      return ReadSignalT<uint16_t, 1>(image, window, signal, saturated, mask_out, level);
    case CV_16UC3:
      return ReadSignalT<uint16_t, 3>(image, window, signal, saturated, mask_out, level);
    default:
      throw std::invalid_argument("ReadDotSignal: unsupported image type " +
                                  std::to_string(image.type()));
  }
}

}  // namespace

namespace {

template <typename T>
int InterpolatedGreenParityT(const cv::Mat& image) {
  // Per parity of (x + y): green values strictly outside the range of their four neighbours'
  // greens, of the pixels whose neighbours differ at all (flat areas tell nothing).
  std::array<int64_t, 2> outside{0, 0}, textured{0, 0};
  for (int y = 1; y + 1 < image.rows; y += 3) {
    const T* up = image.ptr<T>(y - 1);
    const T* row = image.ptr<T>(y);
    const T* down = image.ptr<T>(y + 1);
    for (int x = 1; x + 1 < image.cols; ++x) {
      const int g = row[3 * x + 1];
      const int a = row[3 * (x - 1) + 1], b = row[3 * (x + 1) + 1], c = up[3 * x + 1],
                d = down[3 * x + 1];
      const int lo = std::min(std::min(a, b), std::min(c, d));
      const int hi = std::max(std::max(a, b), std::max(c, d));
      if (hi == lo && g == lo) continue;
      const int p = (x + y) & 1;
      ++textured[p];
      if (g < lo || g > hi) ++outside[p];
    }
  }
  constexpr int64_t kMinEvidence = 200;  // outside pixels of the measured parity
  constexpr double kRatio = 0.1;
  if (textured[0] == 0 || textured[1] == 0) return -1;
  const double f0 = static_cast<double>(outside[0]) / static_cast<double>(textured[0]);
  const double f1 = static_cast<double>(outside[1]) / static_cast<double>(textured[1]);
  if (f0 <= kRatio * f1 && outside[1] >= kMinEvidence) return 0;
  if (f1 <= kRatio * f0 && outside[0] >= kMinEvidence) return 1;
  return -1;
}

}  // namespace

int InterpolatedGreenParity(const cv::Mat& image) {
  switch (image.type()) {
    case CV_8UC3:
      return InterpolatedGreenParityT<uint8_t>(image);
    case CV_16UC3:
      return InterpolatedGreenParityT<uint16_t>(image);
    default:
      return -1;
  }
}

DotSignalPatch ReadDotSignal(const cv::Mat& image, const cv::Rect& window,
                             int interpolated_parity) {
  if ((window & cv::Rect(0, 0, image.cols, image.rows)) != window || window.empty())
    throw std::invalid_argument("ReadDotSignal: window outside the image");
  DotSignalPatch p;
  p.window = window;
  p.signal = cv::Mat1f(window.size(), 0.0f);
  p.level = cv::Mat1f(window.size(), 0.0f);
  p.saturated = cv::Mat1b(window.size(), uchar{0});
  p.full_scale = image.depth() == CV_16U ? 65535 : 255;
  p.interpolated_parity = interpolated_parity;
  ReadSignal(image, window, &p.signal, &p.saturated, nullptr, &p.level);
  return p;
}

void BackgroundPatch::Add(const BackgroundPatch& other) {
  if (sum.empty()) {
    sum = other.sum.clone();
    count = other.count.clone();
    return;
  }
  if (other.sum.size() != sum.size())
    throw std::invalid_argument("BackgroundPatch::Add: window sizes differ");
  sum += other.sum;
  count += other.count;
}

std::vector<BackgroundPatch> BackgroundContribution(const cv::Mat& image,
                                                    const std::vector<Dot>& dots,
                                                    const std::vector<cv::Rect>& windows,
                                                    const DotOptions& options) {
  const cv::Rect whole(0, 0, image.cols, image.rows);
  const int m = options.background_mask_margin_px;
  std::vector<cv::Rect> masks;
  for (const Dot& d : dots)
    masks.emplace_back(d.blob_box.x - m, d.blob_box.y - m, d.blob_box.width + 2 * m,
                       d.blob_box.height + 2 * m);
  std::vector<BackgroundPatch> out(windows.size());
  for (size_t w = 0; w < windows.size(); ++w) {
    const cv::Rect win = windows[w];
    if ((win & whole) != win || win.empty())
      throw std::invalid_argument("BackgroundContribution: window outside the image");
    cv::Mat1b masked(win.size(), uchar{0});
    for (const cv::Rect& r : masks) {
      const cv::Rect o = r & win;
      if (!o.empty()) masked(o - win.tl()).setTo(1);
    }
    BackgroundPatch& p = out[w];
    p.sum = cv::Mat1f(win.size(), 0.0f);
    ReadSignal(image, win, &p.sum, nullptr, &masked);
    p.count = cv::Mat1f(win.size(), 1.0f);
    p.count.setTo(0.0f, masked);
  }
  return out;
}

bool RefineDotOnBackground(const DotSignalPatch& own, const BackgroundPatch& background,
                           const DotOptions& options, Dot* dot, bool allow_curved,
                           ResponseTrial* trial) {
  if (trial) *trial = ResponseTrial{};
  if (background.sum.size() != own.signal.size() || background.count.size() != own.signal.size() ||
      own.level.size() != own.signal.size())
    return false;
  std::vector<FitPixel> px;
  std::vector<ResponsePixel> rpx;
  px.reserve(own.signal.total());
  rpx.reserve(own.signal.total());
  const double full = own.full_scale;
  for (int y = 0; y < own.signal.rows; ++y)
    for (int x = 0; x < own.signal.cols; ++x) {
      const float c = background.count(y, x);
      if (!(c > 0)) return false;
      const double bg = background.sum(y, x) / c;
      // Clipped: at full scale, or on the blob's flat top (in the channel the spot is seen in).
      const bool censored = own.saturated(y, x) != 0 ||
                            (dot->plateau_level > 0 && own.level(y, x) >= dot->plateau_level);
      const double px_x = own.window.x + x, px_y = own.window.y + y;
      if ((own.window.x + x + own.window.y + y) % 2 == own.interpolated_parity) continue;
      px.push_back({px_x, px_y, own.signal(y, x) - bg, censored});
      rpx.push_back({px_x, px_y, own.signal(y, x) / full, bg / full, censored});
    }
  Dot fit = *dot;
  fit.px = dot->centroid_px;
  double plain_var = 0, amplitude = 0;
  if (!FitGaussian(px, &fit, &plain_var, &amplitude) ||
      (fit.px - dot->centroid_px).norm() > options.max_fit_shift_px)
    return false;
  // Through a non-linear response (see the header): kept where the data say so, i.e. where the
  // fitted gamma differs from 1 by more than kResponseSignificance of its own sigma and the
  // residuals are no worse (levels / full scale, squared, in both). Compression noise (JPEG)
  // dominates both fits' residuals, so a variance ratio alone does not tell them apart: under
  // a gamma of 0.6 with JPEG the curved fit lowered the residual variance by only 0-30 % while
  // it moved edge spots' centres 0.4-0.9 px towards the truth.
  // And by more than kMinResponseBend: a linear camera's clipped spots fit gamma within
  // about 0.1 of 1 (the curve then only mimics the flat top that the censoring models).
  constexpr double kResponseSignificance = 3.0;
  Dot curved = fit;
  double gamma_sigma = 0;
  const double curved_var = allow_curved || trial
                                ? FitThroughResponse(rpx, amplitude / full, &curved, &gamma_sigma)
                                : -1.0;
  if (trial && curved_var > 0) *trial = ResponseTrial{true, curved.response_gamma, gamma_sigma};
  if (allow_curved && curved_var > 0 && curved_var <= plain_var / (full * full) &&
      std::abs(curved.response_gamma - 1) >
          std::max(kMinResponseBend, kResponseSignificance * gamma_sigma) &&
      (curved.px - dot->centroid_px).norm() <= options.max_fit_shift_px)
    fit = curved;
  fit.on_background = true;
  *dot = fit;
  return true;
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

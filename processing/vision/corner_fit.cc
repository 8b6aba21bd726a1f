#include "processing/vision/corner_fit.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace msmcal::vision {
namespace {

constexpr int kParams = 9;  // cx, cy, theta1, theta2, sigma, a, b, gx, gy
using Vec = Eigen::Matrix<double, kParams, 1>;
using Mat = Eigen::Matrix<double, kParams, kParams>;

struct Sample {
  double x, y, level;
};

constexpr double kInvSqrt2Pi = 0.3989422804014327;
// The model is sampled at pixel centres while a pixel integrates over its area: the box of 1 px
// has the variance of a Gaussian of sqrt(1/12) px, the least blur an image can show (a sharper
// model would lock onto the pixel grid: 0.2 px off on a rendered board of 4x4-supersampled
// edges without optics blur).
const double kPixelSigma = std::sqrt(1.0 / 12.0);
// Largest |cos| between the two edge normals: narrower wedges (edges within ~25 degrees of each
// other) are refused, and Sheppard's integral below stays well conditioned.
constexpr double kMaxAbsRho = 0.9;

double Phi(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// E[sgn(X) sgn(Y)] for (X, Y) normal with means (h, k), unit variances and correlation rho: the
// level of a checker corner (+1 where the two half-planes agree, -1 elsewhere) blurred by a
// Gaussian, at a point h and k blur sigmas from the two edge lines whose normals make
// cos = rho. With P2(h, k; rho) = P(X > 0, Y > 0) = Phi(h) Phi(k) + T, the pattern is
// 4 P2 - 2 Phi(h) - 2 Phi(k) + 1 = (2 Phi(h) - 1)(2 Phi(k) - 1) + 4 T, where
// T = 1/(2 pi) int_0^asin(rho) exp(-(h^2 + k^2 - 2 h k sin t) / (2 cos^2 t)) dt (Sheppard),
// by 10-point Gauss-Legendre (|rho| <= kMaxAbsRho here).
double CheckerPattern(double h, double k, double rho) {
  static constexpr std::array<double, 5> kX = {0.1488743389816312, 0.4333953941292472,
                                               0.6794095682990244, 0.8650633666889845,
                                               0.9739065285171717};
  static constexpr std::array<double, 5> kW = {0.2955242247147529, 0.2692667193099963,
                                               0.2190863625159820, 0.1494513491505806,
                                               0.0666713443086881};
  const double separable = (2 * Phi(h) - 1) * (2 * Phi(k) - 1);
  // The integrand is at most exp(-(h^2 + k^2)(1 - |rho|) / 2): far from the corner T vanishes.
  if ((h * h + k * k) * (1 - std::abs(rho)) > 60) return separable;
  const double top = std::asin(rho), half = 0.5 * top;
  double t = 0;
  for (int i = 0; i < 5; ++i)
    for (double sgn : {-1.0, 1.0}) {
      const double a = half * (1 + sgn * kX[i]);
      const double c = std::cos(a);
      t += kW[i] * std::exp(-(h * h + k * k - 2 * h * k * std::sin(a)) / (2 * c * c));
    }
  t *= half / (2 * M_PI);
  return separable + 4 * t;
}

// Model value and, when `jac`, its derivatives at sample s (see corner_fit.h).
double Model(const Vec& p, const Sample& s, const Eigen::Vector2d& x0, Vec* jac) {
  const double dx = s.x - p(0), dy = s.y - p(1);
  const double c1 = std::cos(p(2)), s1 = std::sin(p(2));
  const double c2 = std::cos(p(3)), s2 = std::sin(p(3));
  const double sigma = p(4);
  const double rho = std::clamp(c1 * c2 + s1 * s2, -kMaxAbsRho, kMaxAbsRho);
  const double h = (c1 * dx + s1 * dy) / sigma, k = (c2 * dx + s2 * dy) / sigma;
  const double pattern = CheckerPattern(h, k, rho);
  const double g0 = s.x - x0.x(), g1 = s.y - x0.y();
  const double light = 1 + p(7) * g0 + p(8) * g1;
  const double reflected = p(5) + p(6) * pattern;
  if (jac) {
    const double sr = std::sqrt(1 - rho * rho);
    const double dh = 2 * kInvSqrt2Pi * std::exp(-0.5 * h * h) * (2 * Phi((k - rho * h) / sr) - 1);
    const double dk = 2 * kInvSqrt2Pi * std::exp(-0.5 * k * k) * (2 * Phi((h - rho * k) / sr) - 1);
    const double drho =
        4 * std::exp(-(h * h - 2 * rho * h * k + k * k) / (2 * sr * sr)) / (2 * M_PI * sr);
    const double bl = p(6) * light;
    const double sin12 = std::sin(p(2) - p(3));
    (*jac)(0) = -bl * (dh * c1 + dk * c2) / sigma;
    (*jac)(1) = -bl * (dh * s1 + dk * s2) / sigma;
    (*jac)(2) = bl * (dh * (-s1 * dx + c1 * dy) / sigma - drho * sin12);
    (*jac)(3) = bl * (dk * (-s2 * dx + c2 * dy) / sigma + drho * sin12);
    (*jac)(4) = -bl * (dh * h + dk * k) / sigma;
    (*jac)(5) = light;
    (*jac)(6) = pattern * light;
    (*jac)(7) = reflected * g0;
    (*jac)(8) = reflected * g1;
  }
  return reflected * light;
}

// J^T J (full, symmetric) and J^T r of the model at p.
void NormalEquations(const Vec& p, const std::vector<Sample>& samples, const Eigen::Vector2d& x0,
                     Mat* jtj, Vec* jtr) {
  jtj->setZero();
  jtr->setZero();
  for (const auto& s : samples) {
    Vec j;
    const double res = s.level - Model(p, s, x0, &j);
    jtj->selfadjointView<Eigen::Lower>().rankUpdate(j);
    *jtr += j * res;
  }
  *jtj = jtj->selfadjointView<Eigen::Lower>();
}

bool NarrowWedge(const Vec& p) { return std::abs(std::cos(p(2) - p(3))) > kMaxAbsRho; }

double Cost(const Vec& p, const std::vector<Sample>& samples, const Eigen::Vector2d& x0) {
  double c = 0;
  for (const auto& s : samples) {
    const double r = s.level - Model(p, s, x0, nullptr);
    c += r * r;
  }
  return c;
}

}  // namespace

std::optional<CornerFit> FitCorner(const cv::Mat& image, const Eigen::Vector2d& start,
                                   const Eigen::Vector2d& row_dir, const Eigen::Vector2d& col_dir,
                                   double half_window, const CornerFitOptions& options) {
  if (image.type() != CV_32FC1 || !(half_window >= 2) || row_dir.norm() == 0 || col_dir.norm() == 0)
    return std::nullopt;
  // Large squares: the pixels within max_radius_px carry the corner's information; more only
  // cost time.
  half_window = std::min(half_window, options.max_radius_px);
  const int r = static_cast<int>(std::floor(half_window));
  const int cx = static_cast<int>(std::lround(start.x())),
            cy = static_cast<int>(std::lround(start.y()));
  if (cx - r < 0 || cy - r < 0 || cx + r >= image.cols || cy + r >= image.rows) return std::nullopt;
  std::vector<Sample> samples;
  for (int y = cy - r; y <= cy + r; ++y) {
    const float* row = image.ptr<float>(y);
    for (int x = cx - r; x <= cx + r; ++x) {
      const double ddx = x - start.x(), ddy = y - start.y();
      if (ddx * ddx + ddy * ddy <= half_window * half_window)
        samples.push_back({double(x), double(y), row[x]});
    }
  }
  if (samples.size() < 3 * kParams) return std::nullopt;

  // Edge lines along the row and the column: their normals are those directions turned by 90.
  Vec p = Vec::Zero();
  p(0) = start.x();
  p(1) = start.y();
  p(2) = std::atan2(row_dir.x(), -row_dir.y());
  p(3) = std::atan2(col_dir.x(), -col_dir.y());
  p(4) = 1.0;
  if (NarrowWedge(p)) return std::nullopt;
  // Levels (a, b) for the starting geometry, even light.
  {
    Eigen::Matrix2d n = Eigen::Matrix2d::Zero();
    Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
    for (const auto& s : samples) {
      Vec j;
      Model(p, s, start, &j);
      const Eigen::Vector2d a(1, j(6));
      n += a * a.transpose();
      rhs += a * s.level;
    }
    const Eigen::Vector2d l = n.ldlt().solve(rhs);
    if (!l.allFinite()) return std::nullopt;
    p(5) = l(0);
    p(6) = l(1);
  }

  double cost = Cost(p, samples, start);
  double lambda = 1e-3;
  int it = 0;
  Mat jtj;
  Vec jtr;
  for (; it < options.max_iterations; ++it) {
    NormalEquations(p, samples, start, &jtj, &jtr);
    bool stepped = false, converged = false;
    Vec step = Vec::Zero();
    // At the blur's floor with the gradient pushing below it, the blur stays fixed this step.
    const bool hold_blur = p(4) <= kPixelSigma && jtr(4) < 0;
    for (int tries = 0; tries < 10 && !stepped; ++tries) {
      Mat a = jtj;
      a.diagonal() *= 1.0 + lambda;
      Vec g = jtr;
      if (hold_blur) {
        a.row(4).setZero();
        a.col(4).setZero();
        a(4, 4) = 1;
        g(4) = 0;
      }
      step = a.ldlt().solve(g);
      if (!step.allFinite()) return std::nullopt;
      Vec q = p + step;
      q(4) = std::max(q(4), kPixelSigma);
      const double c = NarrowWedge(q) ? HUGE_VAL : Cost(q, samples, start);
      if (c < cost) {
        converged = cost - c < 1e-10 * cost || step.head<2>().norm() < 1e-4;
        p = q;
        cost = c;
        lambda = std::max(lambda * 0.3, 1e-9);
        stepped = true;
      } else {
        lambda *= 10;
      }
    }
    if (!stepped || converged) break;
  }
  if (!p.allFinite()) return std::nullopt;
  const Eigen::Vector2d c(p(0), p(1));
  if ((c - start).norm() > options.max_shift_px || p(4) > half_window ||
      std::abs(p(6)) < options.min_contrast)
    return std::nullopt;
  // Information at the solution.
  NormalEquations(p, samples, start, &jtj, &jtr);
  Eigen::FullPivLU<Mat> lu(jtj);
  if (!lu.isInvertible()) return std::nullopt;
  const double dof = static_cast<double>(samples.size()) - kParams;
  const double s2 = cost / dof;
  CornerFit out;
  out.px = c;
  out.cov_px2 = s2 * lu.inverse().topLeftCorner<2, 2>();
  out.blur_sigma_px = p(4);
  out.residual_rms = std::sqrt(cost / static_cast<double>(samples.size()));
  out.iterations = it;
  if (!out.cov_px2.allFinite()) return std::nullopt;
  return out;
}

}  // namespace msmcal::vision

#pragma once
// Sub-pixel checkerboard corners by fitting a model of the corner to the pixels around it.
//
// cornerSubPix (the refinement OpenCV's detectors end with) finds the point where the image
// gradients in a window are orthogonal to their offsets; under sensor noise it scatters by a few
// hundredths of a pixel, and on the small squares of a slanted board that scatter is what limits
// the board's pose (docs/solver.md, "Checkerboards"). Fitting the corner's intensity model to the
// same window uses every pixel's level, not only the gradients, and gives each corner its own
// covariance.
//
// The model: I(x) = (a + b P(x)) (1 + g . (x - x0)), where P is a checker corner (+1 where the
// half-planes of the two edge lines through the corner c agree, -1 elsewhere; a projected board
// keeps its edges straight, at any angle) blurred by a Gaussian of sigma px, in closed form
// through the bivariate normal distribution, and g the gradient of uneven light, which
// multiplies what the board reflects. The model and a checker corner under any point-symmetric
// blur and any monotonic response are both symmetric under a half turn about c, so the fit's c
// is not biased where the model is only an approximation of the image (another PSF, pixel
// integration, a gamma).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>

namespace msmcal::vision {

struct CornerFitOptions {
  int max_iterations = 30;
  // The fit is refused (the caller keeps its starting point) when it moves the corner by more
  // than this many pixels, when its blur (at least a pixel's own, sqrt(1/12) px) exceeds
  // half_window px, or when the edges'
  // contrast |b| is below min_contrast (levels of `image`).
  double max_shift_px = 1.0;
  double min_contrast = 2.0;
  // The window's radius is at most this (px).
  double max_radius_px = 8.0;
};

struct CornerFit {
  Eigen::Vector2d px = Eigen::Vector2d::Zero();
  // 1-sigma covariance of px (px^2) from the fit's information and its residual variance.
  Eigen::Matrix2d cov_px2 = Eigen::Matrix2d::Identity();
  double blur_sigma_px = 0;
  double residual_rms = 0;  // levels of `image`
  int iterations = 0;
};

// Fits the model above to the pixels of `image` (CV_32FC1) within `half_window` px (a disc)
// of `start`, with the edge lines initially along `row_dir` and `col_dir` (the directions to the
// neighbouring corners along the board's row and column). Empty when the fit fails or is refused
// (see CornerFitOptions) or the window leaves the image.
std::optional<CornerFit> FitCorner(const cv::Mat& image, const Eigen::Vector2d& start,
                                   const Eigen::Vector2d& row_dir, const Eigen::Vector2d& col_dir,
                                   double half_window, const CornerFitOptions& options = {});

}  // namespace msmcal::vision

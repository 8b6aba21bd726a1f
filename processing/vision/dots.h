#pragma once
// Laser-dot extraction (MSM paper Sec. III-D): threshold, connected blobs, intensity-weighted
// centroid and its covariance = pixel scatter / N.
//
// Images: CV_8U or CV_16U, 1 channel (mono: brightness) or 3 channels (BGR: the green channel
// minus the larger of blue and red, so that white board squares do not count as laser light).
// In mono images the local background (board squares) is removed first by a top-hat.
// Pixel (0, 0) is the centre of the top-left pixel.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace msmcal::vision {

struct Dot {
  Eigen::Vector2d px = Eigen::Vector2d::Zero();       // weighted centroid, pixels
  Eigen::Matrix2d cov_px2 = Eigen::Matrix2d::Zero();  // covariance of the centroid, px^2
  int num_pixels = 0;                                 // N, pixels above threshold
  double peak = 0;  // highest signal in the blob (image units)
};

struct DotOptions {
  // Signal threshold as a fraction of the image type's full scale (255 or 65535).
  double threshold_fraction = 0.15;
  int min_pixels = 12;   // smaller blobs are noise or board-corner residue
  int max_pixels = 400;  // larger blobs are reflections / board squares, not a dot
  // Ratio of the scatter's principal std devs. Laser spots are round (<= 1.2 in the simulator even
  // on oblique boards); checkerboard X-junction residue of the top-hat is >= 1.4.
  double max_elongation = 1.3;
  // Fraction of a blob's pixels allowed at full scale (saturated) before it is rejected.
  double max_saturated_fraction = 0.9;
  // Mono images: the signal is the white top-hat with this square kernel (odd, pixels; larger
  // than a dot, smaller than a board square), so dots on light squares stand out. 0: raw
  // brightness.
  int background_kernel_px = 11;
  std::string Validate() const;  // empty when valid, else names field, value and constraint
};

struct DotRejections {
  int too_small = 0, too_large = 0, elongated = 0, saturated = 0;
};

// All dots of an image, ordered by row of their first pixel (raster order). Throws
// std::invalid_argument for unsupported image types.
std::vector<Dot> DetectDots(const cv::Mat& image, const DotOptions& options = {},
                            DotRejections* rejections = nullptr);

// Reference pipeline for the benchmark: cv::inRange + connectedComponentsWithStats + moments
// per component (no intensity weighting, no rejection but size).
std::vector<Dot> DetectDotsOpenCvReference(const cv::Mat& image, const DotOptions& options = {});

}  // namespace msmcal::vision

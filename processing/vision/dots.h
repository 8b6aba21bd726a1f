#pragma once
// Laser-dot extraction (MSM paper Sec. III-D): threshold, connected blobs, intensity-weighted
// centroid and its covariance = pixel scatter / N; optionally (the default) the centre is then
// refined by a least-squares fit of a clipped Gaussian spot (DotCentre::kGaussianFit).
//
// Images: CV_8U or CV_16U, 1 channel (mono: brightness) or 3 channels (BGR: the green channel,
// and a blob counts as laser light only if somewhere it is greener than it is blue or red, by
// `min_green_excess_fraction`: white board squares and specks are not). The local background
// (board squares) is removed first by a top-hat. Green minus max(blue, red) is not the signal:
// a green spot saturates the green channel on a light square while blue and red still rise,
// and the spot vanishes from it.
// Pixel (0, 0) is the centre of the top-left pixel.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace msmcal::vision {

struct Dot {
  Eigen::Vector2d px = Eigen::Vector2d::Zero();       // centre, pixels (DotOptions::centre)
  Eigen::Matrix2d cov_px2 = Eigen::Matrix2d::Zero();  // covariance of the centre, px^2
  int num_pixels = 0;                                 // N, pixels above threshold
  double peak = 0;                                    // highest signal in the blob (image units)
  // The image's level (before the top-hat) at that pixel: peak_level - peak is the background
  // under the spot, full scale - that the most a spot can show there (its headroom).
  double peak_level = 0;
  // Level at and above which the spot's pixels are taken as clipped (bounds, not measurements):
  // full scale, or lower where the blob has a flat top (a camera or a conversion that clips below
  // full scale, a gain, blur or compression applied after clipping: DotOptions::
  // plateau_tolerance_fraction).
  double plateau_level = 0;
  bool fitted = false;  // centre and covariance from the Gaussian fit (else: weighted centroid)
  bool on_background = false;  // fitted over a background from other images (RefineDots...)
  // Fitted through a non-linear response (RefineDotOnBackground): the image's level is
  // (background^(1/gamma) + spot)^gamma, in units of full scale; 1 where the plain fit was kept.
  double response_gamma = 1;
  int saturated_pixels = 0;
  // The blob: pixels above threshold (bounding box), their weighted centroid and scatter (px^2).
  cv::Rect blob_box;
  Eigen::Vector2d centroid_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d scatter_px2 = Eigen::Matrix2d::Zero();
};

// How a blob's centre is measured.
//  kWeightedCentroid: the paper's intensity-weighted centroid of the pixels above threshold,
//    covariance = pixel scatter / N. Biased where the spot is clipped (saturated on a light
//    square) or cut by the threshold at a pixel boundary (pixel locking): measured on the rig
//    simulator 0.04 px on dark squares, 0.08 px on light ones, 0.12 px across a square edge.
//  kGaussianFit: starts there, then fits  b0 + A exp(-(p - c)^T P (p - c) / 2)  to the signal in
//    a window around the blob (tails below threshold included), saturated pixels as lower
//    bounds; covariance = residual variance x (J^T J)^-1 of the centre. A fit that does not
//    converge, or moves the centre by more than `max_fit_shift_px`, keeps the centroid.
enum class DotCentre { kWeightedCentroid, kGaussianFit };

struct DotOptions {
  // Signal threshold as a fraction of the image type's full scale (255 or 65535).
  double threshold_fraction = 0.15;
  int min_pixels = 12;   // smaller blobs are noise or board-corner residue
  int max_pixels = 400;  // larger blobs are reflections / board squares, not a dot
  // Ratio of the scatter's principal std devs, in the image. Loose by default: a round spot on a
  // plate tilted 60 deg to the camera is 2x elongated in the image; checkerboard X-junction
  // residue of the top-hat is mostly 3-7x. The solver checks roundness again in the board's own
  // plane (PipelineOptions::max_surface_elongation) and refuses elongated blobs at corners.
  double max_elongation = 3.0;
  // Fraction of a blob's pixels allowed at full scale (saturated) before it is rejected. The
  // Gaussian fit places a clipped spot by its flanks (below threshold too), so the default keeps
  // them all: a spot on a light square is a saturated plateau in the top-hat, 80-95 % of its
  // blob (0.9 lost such dots at random, and with them whole sessions). With
  // DotCentre::kWeightedCentroid a saturated centre is unusable: use about 0.5.
  double max_saturated_fraction = 1.0;
  // A blob whose brightest pixels form a flat top is taken as clipped there (Dot::plateau_level),
  // at full scale or below it. A clean flat top is clipped within 1 % of its maximum; one that
  // compression (JPEG) or a camera's own filtering rippled, down to twice its deepest dip, but
  // at most this fraction of the maximum: the rippled pixels are bounds, not measurements.
  // Measured, a mono JPEG of quality 85 (issue 15's independent-like scene): clipped spots
  // 0.3-0.4 px off truth with 1 %, 0.02-0.07 px with the ripple taken as clipped.
  double plateau_tolerance_fraction = 0.06;
  // The signal (mono brightness, BGR green) is the white top-hat with this square kernel (odd,
  // pixels; larger than a dot, smaller than a board square), so dots on light squares stand out. 0:
  // raw brightness.
  int background_kernel_px = 11;
  // BGR only: a blob is kept if its largest green - max(blue, red) reaches this fraction of
  // full scale.
  double min_green_excess_fraction = 0.05;
  DotCentre centre = DotCentre::kGaussianFit;
  int fit_margin_px = 3;  // window = blob bounding box grown by this many pixels
  // BGR from a Bayer sensor: when the image shows that half of its green values were
  // interpolated (InterpolatedGreenParity), fit the spots to the measured half only.
  bool native_green_only = true;
  double max_fit_shift_px = 1.5;  // a fit that moves the centre further is not used
  // Background from other images (RefineDotOnBackground): each image's own dots are masked with
  // their blob box grown by this many pixels (the spot's tails below threshold).
  int background_mask_margin_px = 5;
  std::string Validate() const;  // empty when valid, else names field, value and constraint
};

struct DotRejections {
  int too_small = 0, too_large = 0, elongated = 0, saturated = 0;
  int not_green = 0;      // BGR: blobs nowhere greener than blue and red
  int too_faint = 0;      // second (adaptive) pass: far fainter than the frame's brightest spot
  int fit_fallbacks = 0;  // kept dots whose Gaussian fit was not used (centroid kept)
  // Found at the same place in images of one static scene whose light has nothing in common:
  // the scene's own structure (solver: PipelineOptions::static_blob_radius_px).
  int static_blob = 0;
};

// Every blob the detector looked at, with its fate (msmcal solve --explain).
struct DotCandidate {
  cv::Rect box;
  Eigen::Vector2d centroid_px = Eigen::Vector2d::Zero();
  int num_pixels = 0;
  double peak = 0;
  double elongation = 1;
  int saturated_pixels = 0;
  bool kept = false;
  std::string reason;  // why it was refused, or how it was measured
};

// All dots of an image, ordered by row of their first pixel (raster order). Throws
// std::invalid_argument for unsupported image types. `candidates` (optional) receives every
// blob above the threshold with its fate (the flood fill stops growing a blob past
// max_pixels + 1).
std::vector<Dot> DetectDots(const cv::Mat& image, const DotOptions& options = {},
                            DotRejections* rejections = nullptr,
                            std::vector<DotCandidate>* candidates = nullptr);

// The background of a static scene (camera and boards fixed, the laser spots changing from
// image to image): per pixel and channel the smallest and second smallest value over the images
// added. Without(image) is the scene without that image's own light: the smallest over the
// others (`image` must be one of those added; where it holds the smallest, the second).
class StaticBackground {
 public:
  // False (and nothing added) if `image` differs in size or type from the first one.
  bool Add(const cv::Mat& image);
  cv::Mat Without(const cv::Mat& image) const;
  size_t count() const { return count_; }

 private:
  cv::Mat lo_, lo2_;
  size_t count_ = 0;
};

// The same over a known background (same size and type; e.g. the scene without the spots):
// the signal is image - background instead of the top-hat, so board squares, their edges and
// corners cancel; saturation and flat tops are read from `image`, greenness (BGR) from the
// difference (what the spot added). options.background_kernel_px is not used.
std::vector<Dot> DetectDotsOverBackground(const cv::Mat& image, const cv::Mat& background,
                                          const DotOptions& options,
                                          DotRejections* rejections = nullptr,
                                          std::vector<DotCandidate>* candidates = nullptr);
// The same with settings from the difference's own noise and the board's squares
// (AdaptiveDotOptions of image - background, computed once); `used` gets them.
std::vector<Dot> DetectDotsOverBackgroundAdaptive(const cv::Mat& image, const cv::Mat& background,
                                                  double square_px, const DotOptions& base,
                                                  DotOptions* used = nullptr,
                                                  DotRejections* rejections = nullptr,
                                                  std::vector<DotCandidate>* candidates = nullptr);

// Settings for one image from its own data, for spots the defaults miss (small or faint spots,
// boards of small squares): the top-hat kernel from the board's square size (the largest odd
// size below 0.8 squares, 5..61 px: a spot smaller than a square survives it, a square does
// not), the threshold from the image's noise (the top-hat's median plus 8 robust sigmas of the
// pixel-to-pixel noise, between 2 % of full scale and base's), min_pixels at most 4 (a spot of
// sigma 0.8 px 8 sigmas above the noise covers about 4 pixels), max_pixels and the fit margin
// from the kernel. `square_px`: the board's square size in the image.
DotOptions AdaptiveDotOptions(const cv::Mat& image, double square_px, const DotOptions& base);

// ---- Refinement over a background measured in other images ----
// In a series of images of one static scene (camera and boards fixed, the laser dots moving
// from image to image, as in step 2, or in step 1 at one sliding pose), the background under a
// dot is measured in the other images, where those pixels are dot-free. The Gaussian fit then
// sees the spot alone, also across square edges and corners, where the top-hat's background is
// wrong (measured on the rig simulator: 0.11-0.16 px error at edges, 0.01-0.03 px on this
// background). The dot's covariance is that fit's.

// Window of a dot's fit: its blob box grown by options.fit_margin_px, inside the image.
cv::Rect DotFitWindow(const Dot& dot, const cv::Size& image_size, const DotOptions& options);

// The dot signal (mono: brightness; BGR: green minus the larger of blue and red) of the image's
// pixels in `window`, and which of them are saturated.
struct DotSignalPatch {
  cv::Rect window;
  cv::Mat1f signal;
  cv::Mat1f level;  // the channel the spot is seen in (mono: brightness; BGR: green), as read
  cv::Mat1b saturated;
  double full_scale = 255;  // the image type's full scale (255 or 65535)
  // Pixels (x + y) % 2 == this (image coordinates) were interpolated, not measured, and are
  // left out of the fit; -1: every pixel was measured (InterpolatedGreenParity).
  int interpolated_parity = -1;
};
DotSignalPatch ReadDotSignal(const cv::Mat& image, const cv::Rect& window,
                             int interpolated_parity = -1);

// ---- Colour cameras: a Bayer mosaic's interpolated green ----
// A colour camera's sensor measures one colour per pixel (a Bayer mosaic: green on one of the
// two checkerboard parities of (x + y), red and blue on the other) and interpolates the rest.
// A green spot of sigma ~1.3 px is then half measured and half interpolated from its
// neighbours, and on a clipped spot the interpolated pixels mix clipped and unclipped values:
// the Gaussian fit over every pixel was 0.13 px off (0.03 px over the measured half; planes
// 0.12 deg -> 0.017 deg, RobustnessSimTest.BayerDemosaicedColourCameraSolves).
// Read from the data: an interpolated green (bilinear, or along an edge) lies between the
// greens of its four neighbours, a measured one is outside their range wherever there is noise
// or texture (about a third of the pixels). Returns the parity of (x + y) whose green is
// interpolated when, over the image's textured pixels, that parity is outside its neighbours'
// range at most a tenth as often as the other (and the other at least 200 times); -1 for mono
// images, three independently measured channels, or too little texture to tell.
int InterpolatedGreenParity(const cv::Mat& image);

// Sums of the dot signal over images, per pixel of a window, with each image's own dots masked.
struct BackgroundPatch {
  cv::Mat1f sum;
  cv::Mat1f count;
  void Add(const BackgroundPatch& other);  // same size (or this one empty)
};
// One image's contribution to the background of each of `windows`; `dots` are its own dots.
std::vector<BackgroundPatch> BackgroundContribution(const cv::Mat& image,
                                                    const std::vector<Dot>& dots,
                                                    const std::vector<cv::Rect>& windows,
                                                    const DotOptions& options = {});
// Refits `dot` to own.signal - background (its mean); returns false and leaves the dot as it
// was where a window pixel has no dot-free view, the fit fails or moves the centre by more
// than options.max_fit_shift_px from the blob's centroid, or where `own` lacks its levels (read it
// with ReadDotSignal). Sets dot->on_background.
// Where the camera's response is not linear (a gamma curve, a LUT), a spot adds less level over
// a light background than over a dark one, so a spot across a square edge is lopsided after the
// background is subtracted and its fitted centre moves towards the dark side (0.3-1.3 px under
// a gamma of 0.6, perpendicular to the edge). So the spot is also fitted through a response
// level = full x (b^(1/gamma) + A g)^gamma (b: the measured background, in units of full scale;
// g the Gaussian), gamma fitted; it is kept where gamma differs from 1 by more than 3 of its
// sigmas and the residuals are no worse (a linear camera gives gamma ~ 1: the plain fit stays).
// The curved fit as RefineDotOnBackground tried it, whether or not it was kept: a camera's
// response is one for all its spots, so a caller can pool these over many dots and refit with
// `allow_curved` false where the pool says the camera is linear (a single dot's gamma can come
// out 0.2-0.8 from noise, on about one dot in ten of a linear camera, and move it by up to
// 0.4 px). converged false: no curved fit.
// How far from 1 a fitted gamma must be before a response curve is taken (per dot here, per
// camera by a caller pooling the trials): a linear camera's clipped spots fit within about 0.1.
inline constexpr double kMinResponseBend = 0.15;
struct ResponseTrial {
  bool converged = false;
  double gamma = 1;
  double gamma_sigma = 0;
};
bool RefineDotOnBackground(const DotSignalPatch& own, const BackgroundPatch& background,
                           const DotOptions& options, Dot* dot, bool allow_curved = true,
                           ResponseTrial* trial = nullptr);

// Reference pipeline for the benchmark: cv::inRange + connectedComponentsWithStats + moments
// per component (no intensity weighting, no rejection but size).
std::vector<Dot> DetectDotsOpenCvReference(const cv::Mat& image, const DotOptions& options = {});

}  // namespace msmcal::vision

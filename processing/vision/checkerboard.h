#pragma once
// Checkerboard detection with the interchange format's canonical corner order.
//
// Board convention (interchange-format.md; the renderer draws exactly this): the square whose
// minimum inner corner is (i, j), i in [-1, cols-1], j in [-1, rows-1], is dark iff (i + j) is
// even; board frame X along the cols direction, Y along rows, Z = X x Y into the board (away
// from the camera). Corners are returned as index r * cols + c for board point
// (c * square, r * square, 0), whatever the board's rotation in the image.
//
// Detection is a fallback chain (BoardMethod), cheapest first, each refined at full resolution
// with cv::cornerSubPix: findChessboardCornersSB on a ladder of downscaled copies, SB at full
// resolution, the classic quad detector (cv::findChessboardCorners with adaptive threshold and
// its fast check; it finds small, blurred or unevenly lit boards that SB misses; boards of at
// most classic_max_corners), then SB on a 2x upscaled copy (squares below ~12 px; small images
// only). Every candidate grid must pass a
// geometric check (corners refined within a fraction of a square of where the detector put them, a
// locally consistent grid; a rough grid, at most a square off, is judged after its refinement)
// before it is accepted; the method that found the board is recorded.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace msmcal::vision {

struct BoardSize {
  int cols = 0;  // inner corners along X
  int rows = 0;  // inner corners along Y
};

// The detectors of the fallback chain, in the order they are tried.
// kContrastCheck is not a detector: the attempt that stopped the chain on an image without the
// contrast a board needs (a black, blank or saturated frame; see min_contrast_levels).
enum class BoardMethod { kSbCoarse, kSbFull, kClassic, kSbUpscaled, kContrastCheck };
// "sb_coarse" | "sb_full" | "classic" | "sb_upscaled" | "contrast_check"
const char* ToString(BoardMethod method);

struct CheckerboardOptions {
  // The coarse search runs on an image whose longer side is at most this many pixels.
  int coarse_max_side_px = 1400;
  // Fallbacks, tried in this order when the coarse SB search fails.
  bool try_sb_full = true;
  bool try_sb_upscaled = true;  // only where the upscaled longer side is <= upscale_max_side_px
  int upscale_max_side_px = 3300;
  bool try_classic = true;
  int classic_max_corners = 400;  // its cost explodes with the board's size
  // Where SB found nothing on the whole image, before the classic and upscaled searches on it:
  // SB at full resolution, SB upscaled x2 and x3 and classic on each of the image's most
  // checker-like regions (TexturedRegions), at most this many (0: off). SB misses boards on a
  // whole frame that it finds on their surroundings; the upscaled search, too costly on a whole
  // frame, is affordable on a region; the classic one can spend minutes failing on a whole frame.
  int textured_regions = 4;
  // A grid is refused if cornerSubPix moves a corner by more than this fraction of the local
  // square size (the detector latched on something else), or if a corner deviates from the
  // average of its neighbours' prediction by more than this fraction (not a grid).
  double max_refine_shift_squares = 0.35;
  // cornerSubPix's half window: this fraction of the smallest distance between neighbouring
  // corners (along rows or columns, so that a board seen at a slant counts by its foreshortened
  // side), but at least refine_window_min_px and at most half that distance (2..15 px). A window
  // that covers only the blurred edges next to the corner is biased by a non-linear response:
  // on a 60-degree slanted board of 10 x 18 px squares under a gamma of 0.6 after a 3 x 3
  // filter, 0.35 px RMS per axis with a 2 px half window (0.3 of the spacing), 0.025 px with
  // 5 px. Larger fractions moved corners of OpenCV's sample photographs by 3-8 px.
  double refine_window_squares = 0.3;
  double refine_window_min_px = 5;
  double max_grid_irregularity_squares = 0.25;
  // After cornerSubPix, each corner is refined by fitting a model of a blurred corner to the
  // levels within the same window (vision/corner_fit.h); a corner whose fit fails keeps
  // cornerSubPix's point. The fit reads the same window as cornerSubPix, but at most
  // fit_max_radius_px around the corner.
  bool fit_corners = true;
  double fit_max_radius_px = 8;
  // No detector runs on an image whose grey levels (8-bit scale, after a 3 x 3 median and 4 x 4
  // averaging, which take hot pixels and sensor noise out and keep any region a board could be
  // seen in) span less than
  // this between their 0.1 and 99.9 percentiles: a board is dark and light squares. A black
  // frame cost ~3 s per board in the SB searches and found nothing. 0: always search.
  double min_contrast_levels = 8;
  // A BoardHint's region: the board it comes from grown by this many of its squares on every
  // side (the outer squares and the quiet zone the detectors need, plus a small shift).
  double hint_margin_squares = 3;
  std::string Validate() const;
};

// Where a board was found in another image of the same view (same camera, board not moved):
// DetectCheckerboard first runs that detector at that scale on that region only, and runs the
// whole chain when it fails there. In a session's frames the world board does not move, and the
// detector that finds it in one frame usually finds it in the others; a 2x upscaled SB search
// on the region costs a fraction of one on the whole image (docs/solver.md, "Checkerboards").
struct BoardHint {
  BoardMethod method = BoardMethod::kSbCoarse;
  double scale = 1.0;
  cv::Rect region;  // full-resolution pixels
  // The board does not move between the images of its view (the world board before a fixed
  // camera): it can only be in `region`, and the classic detector, the chain's costliest, runs
  // there instead of on the whole image (124 s failing on a 1600 x 1200 frame whose world board
  // a plate covered in part, 0.2 s on the region).
  bool fixed = false;
};

// One detector's try on one board (for diagnostics: msmcal solve --explain).
struct BoardAttempt {
  BoardMethod method = BoardMethod::kSbCoarse;
  double scale = 1.0;     // image scale the detector ran on
  bool found = false;     // the detector returned a grid
  bool accepted = false;  // and it passed the geometric check
  std::string note;       // why a found grid was refused (or that it was accepted as rough)
  cv::Rect region;        // the region it ran on (empty: the whole image)
  bool textured = false;  // that region is one of TexturedRegions' (else a hint's)
  double seconds = 0;     // the detector's wall time (diagnostics only: --explain)
};

// The parts of an 8-bit grey image that look like a checkerboard, largest first: where the
// gradient varies in two directions over a window of about 1/60 of the image's longer side (the
// smaller eigenvalue of the averaged structure tensor, above the geometric mean of its median and
// its maximum: edges, flat areas and noise stay below), closed by the window (squares larger than
// it leave holes). A patch narrower than two windows is a point-like feature (a laser spot, a
// plate's corner) and is left out. Each region is grown by a window; regions that cannot hold
// `size` (4 x 4 px per inner corner) or cover most of the image are left out.
std::vector<cv::Rect> TexturedRegions(const cv::Mat& gray, BoardSize size, int max_regions);

struct CheckerboardDetection {
  std::vector<Eigen::Vector2d> corners_px;  // canonical order, size cols * rows
  // Half size of the square window the sub-pixel refinement read around each corner: a bright
  // spot (laser dot) reaching into it biases that corner (up to 1.6 px on the simulator).
  int refine_half_window_px = 0;
  BoardMethod method = BoardMethod::kSbCoarse;  // the detector that found the board
  double scale = 1.0;                           // at this image scale
  bool hinted = false;   // in a BoardHint's region (found where another image had it)
  double square_px = 0;  // median distance between neighbouring corners, pixels
  // Corners refined by the corner model (CheckerboardOptions::fit_corners); the others keep
  // cornerSubPix's point.
  int corners_fitted = 0;
};

// The hint a found board gives for other images of `image_size` (region clipped to the image).
BoardHint HintFrom(const CheckerboardDetection& board, cv::Size image_size,
                   const CheckerboardOptions& options);

// Finds one board of exactly `size` in `image` (8/16-bit, 1 or 3 channels). `mask` (optional,
// CV_8U, same size, nonzero = usable) hides regions such as an already found board. Empty when
// not found. `attempts` (optional) receives every detector's try, in order. `hint` (optional):
// tried first (BoardHint).
std::optional<CheckerboardDetection> DetectCheckerboard(
    const cv::Mat& image, BoardSize size, const CheckerboardOptions& options = {},
    const cv::Mat& mask = cv::Mat(), std::vector<BoardAttempt>* attempts = nullptr,
    const BoardHint* hint = nullptr);

// Flags (1) the corners of `board` whose refinement window no bright spot reached. A spot is
// given by its blob's bounding box (pixels above the dot threshold); its light reaches 3 px
// beyond the box's half diagonal from the box centre. A laser dot in the window pulls the corner
// (up to 1.6 px on the simulator's step 2, docs/solver.md "Checkerboards").
std::vector<char> CornersClearOfSpots(const CheckerboardDetection& board,
                                      const std::vector<cv::Rect>& spot_boxes);

// Finds several boards of different sizes in one image: the one with more corners first, then the
// others with the found boards masked out. Result i corresponds to sizes[i].
// `attempts` (optional): per size, as DetectCheckerboard's. `hints` (optional): per size, a
// hint or nullopt.
std::vector<std::optional<CheckerboardDetection>> DetectCheckerboards(
    const cv::Mat& image, const std::vector<BoardSize>& sizes,
    const CheckerboardOptions& options = {},
    std::vector<std::vector<BoardAttempt>>* attempts = nullptr,
    const std::vector<std::optional<BoardHint>>* hints = nullptr);

// Reorders a grid of corners (row-major rows x cols, as OpenCV returns them) into the canonical
// order using the handedness in the image and the colour of the outer squares in `gray` (8-bit).
std::vector<Eigen::Vector2d> CanonicalCornerOrder(const std::vector<Eigen::Vector2d>& grid,
                                                  BoardSize size, const cv::Mat& gray);

// The homography (CV_64F 3 x 3; empty if it cannot be fitted) that maps board points in squares
// (c, r) to the detection's pixels.
cv::Mat BoardHomography(const CheckerboardDetection& board, BoardSize size);

// The outline of the board's squares area in the image (board points (-1, -1), (cols, -1),
// (cols, rows), (-1, rows) in squares, mapped by the homography of the detected corners), and
// whether a pixel lies inside it grown by `margin_squares`.
std::vector<Eigen::Vector2d> SquaresOutline(const CheckerboardDetection& board, BoardSize size,
                                            double margin_squares = 0.0);
bool InsideOutline(const std::vector<Eigen::Vector2d>& outline, const Eigen::Vector2d& px);

// The board's plane as the image shows it: whether a pixel lies within the squares area grown
// by `margin_squares` (any margin, infinity included: the whole plane short of its horizon).
// Mapped back through the homography of the detected corners, so a margin far larger than the
// board stays exact where an outline's corners would fall behind the camera. Contains nothing
// where the homography cannot be fitted.
class BoardArea {
 public:
  BoardArea(const CheckerboardDetection& board, BoardSize size);
  bool Contains(const Eigen::Vector2d& px, double margin_squares) const;

 private:
  BoardSize size_;
  bool valid_ = false;
  cv::Matx33d image_to_board_;
  double front_sign_ = 1.0;  // sign of the mapped w on the board's side of the horizon
};

// Single-channel float levels of an image in 8-bit units (BGR -> gray without rounding, 16-bit
// scaled by 1/257); where `mask` (optional) is zero, 128.
cv::Mat ToGray32F(const cv::Mat& image, const cv::Mat& mask = cv::Mat());
// 8-bit single-channel version of an image (BGR -> gray, 16-bit -> scaled).
cv::Mat ToGray8(const cv::Mat& image);
// 8-bit BGR copy of an image (gray -> BGR, 16-bit -> scaled by 1/257), for drawing on. Throws
// std::invalid_argument for an empty image or other depths / channel counts, naming `what`.
cv::Mat ToBgr8(const cv::Mat& image, const std::string& what = "ToBgr8");

}  // namespace msmcal::vision

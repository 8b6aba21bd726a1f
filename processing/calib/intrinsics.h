#pragma once
// Intrinsic camera calibration from chessboard views (OpenCV: findChessboardCorners, cornerSubPix,
// calibrateCamera) into the project's CameraModel (pinhole + k1 k2 p1 p2 k3, pixel (0,0) at the
// centre of the top-left pixel). Pure computation: images in, numbers out, no file I/O.

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "processing/geometry/camera_model.h"

namespace msmcal::calib {

// A chessboard by its inner corners (cols x rows) and square side in millimetres.
struct BoardSpec {
  int cols = 9;
  int rows = 6;
  double square_mm = 10.0;
  // Empty if valid, else "BoardSpec.<field> = <value>: <constraint>".
  std::string Validate() const;
};

// Parses "COLSxROWS" (e.g. "9x6"); empty on malformed text.
std::optional<BoardSpec> ParseBoardSize(const std::string& text, double square_mm);

// Inner corners in the board's row-major order (OpenCV's order), sub-pixel refined, or empty when
// the board is not found. Accepts 8/16-bit, 1/3/4-channel images.
std::optional<std::vector<cv::Point2f>> DetectChessboard(const cv::Mat& image,
                                                         const BoardSpec& board);

struct IntrinsicsResult {
  bool ok = false;
  std::string message;  // why it failed, when !ok
  geometry::CameraModel camera;
  double rms_px = 0;                    // overall RMS reprojection error
  std::vector<double> per_view_rms_px;  // one per input view
};

// Calibrates from the corners of >= 3 views of the same board in images of `image_size`.
IntrinsicsResult CalibrateIntrinsics(const std::vector<std::vector<cv::Point2f>>& views,
                                     const BoardSpec& board, cv::Size image_size);

}  // namespace msmcal::calib

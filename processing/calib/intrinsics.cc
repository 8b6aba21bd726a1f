#include "processing/calib/intrinsics.h"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <regex>
#include <sstream>

namespace msmcal::calib {

std::string BoardSpec::Validate() const {
  std::ostringstream out;
  if (cols < 2 || cols > 100) {
    out << "BoardSpec.cols = " << cols << ": must be in [2, 100] inner corners";
  } else if (rows < 2 || rows > 100) {
    out << "BoardSpec.rows = " << rows << ": must be in [2, 100] inner corners";
  } else if (!(square_mm > 0) || !std::isfinite(square_mm)) {
    out << "BoardSpec.square_mm = " << square_mm << ": must be > 0";
  }
  return out.str();
}

std::optional<BoardSpec> ParseBoardSize(const std::string& text, double square_mm) {
  std::smatch m;
  static const std::regex kPattern(R"((\d+)[xX](\d+))");
  if (!std::regex_match(text, m, kPattern)) return std::nullopt;
  BoardSpec board;
  board.cols = std::stoi(m[1]);
  board.rows = std::stoi(m[2]);
  board.square_mm = square_mm;
  return board;
}

std::optional<std::vector<cv::Point2f>> DetectChessboard(const cv::Mat& image,
                                                         const BoardSpec& board) {
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = image;
  }
  if (gray.depth() == CV_16U) gray.convertTo(gray, CV_8U, 1.0 / 256.0);
  const cv::Size pattern(board.cols, board.rows);
  std::vector<cv::Point2f> corners;
  const bool found = cv::findChessboardCorners(
      gray, pattern, corners,
      cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK);
  if (!found) return std::nullopt;
  cv::cornerSubPix(gray, corners, cv::Size(11, 11), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
  return corners;
}

IntrinsicsResult CalibrateIntrinsics(const std::vector<std::vector<cv::Point2f>>& views,
                                     const BoardSpec& board, cv::Size image_size) {
  IntrinsicsResult result;
  if (std::string error = board.Validate(); !error.empty()) {
    result.message = error;
    return result;
  }
  if (views.size() < 3) {
    result.message =
        "need at least 3 views with the board found, have " + std::to_string(views.size());
    return result;
  }
  const size_t n = static_cast<size_t>(board.cols) * board.rows;
  std::vector<cv::Point3f> board_points;
  for (int r = 0; r < board.rows; ++r) {
    for (int c = 0; c < board.cols; ++c) {
      board_points.emplace_back(static_cast<float>(c * board.square_mm),
                                static_cast<float>(r * board.square_mm), 0.f);
    }
  }
  for (size_t v = 0; v < views.size(); ++v) {
    if (views[v].size() != n) {
      result.message = "view " + std::to_string(v) + " has " + std::to_string(views[v].size()) +
                       " corners, the board has " + std::to_string(n);
      return result;
    }
  }
  std::vector<std::vector<cv::Point3f>> object_points(views.size(), board_points);
  cv::Mat K, dist, per_view;
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat std_intrinsics, std_extrinsics;
  try {
    result.rms_px = cv::calibrateCamera(
        object_points, views, image_size, K, dist, rvecs, tvecs, std_intrinsics, std_extrinsics,
        per_view, 0,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, DBL_EPSILON));
  } catch (const cv::Exception& e) {
    result.message = std::string("calibrateCamera failed: ") + e.what();
    return result;
  }
  for (int i = 0; i < per_view.rows; ++i) result.per_view_rms_px.push_back(per_view.at<double>(i));
  geometry::CameraModel& cam = result.camera;
  cam.width = image_size.width;
  cam.height = image_size.height;
  cam.fx = K.at<double>(0, 0);
  cam.fy = K.at<double>(1, 1);
  cam.cx = K.at<double>(0, 2);
  cam.cy = K.at<double>(1, 2);
  for (int i = 0; i < 5; ++i) cam.distortion[i] = dist.at<double>(i);
  result.ok = std::isfinite(result.rms_px);
  if (!result.ok) result.message = "calibrateCamera returned a non-finite RMS";
  return result;
}

}  // namespace msmcal::calib

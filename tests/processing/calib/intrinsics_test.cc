// Intrinsic calibration: recovered ground truth on synthetic chessboard renders (known camera
// with distortion), and OpenCV's real sample photos left01..14.jpg (Debian's opencv-doc).
#include "processing/calib/intrinsics.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

namespace msmcal::calib {
namespace {

geometry::CameraModel TruthCamera() {
  geometry::CameraModel cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = 560;
  cam.fy = 555;
  cam.cx = 322.5;
  cam.cy = 236.0;
  cam.distortion = {-0.18, 0.06, 0.0008, -0.0006, 0.0};
  return cam;
}

// Renders a white-bordered chessboard (cols x rows inner corners) seen by `cam` with
// cam_from_board = (R, t), centred on the board's middle; 2x2 supersampling.
cv::Mat RenderBoard(const geometry::CameraModel& cam, const BoardSpec& board,
                    const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  cv::Mat image(cam.height, cam.width, CV_8UC1);
  const double s = board.square_mm;
  const Eigen::Vector3d centre((board.cols - 1) * s / 2, (board.rows - 1) * s / 2, 0);
  const Eigen::Vector3d n = R.col(2);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      int sum = 0;
      for (int sy = 0; sy < 2; ++sy) {
        for (int sx = 0; sx < 2; ++sx) {
          const Eigen::Vector3d d =
              cam.Unproject(Eigen::Vector2d(x + (sx - 0.5) / 2.0, y + (sy - 0.5) / 2.0));
          const double lambda = n.dot(t) / n.dot(d);
          const Eigen::Vector3d p = R.transpose() * (lambda * d - t) + centre;
          const int i = static_cast<int>(std::floor(p.x() / s)) + 1;  // squares -1..cols-1
          const int j = static_cast<int>(std::floor(p.y() / s)) + 1;
          int value = 255;  // white border and background
          if (i >= 0 && i <= board.cols && j >= 0 && j <= board.rows) {
            value = ((i + j) % 2 == 0) ? 0 : 255;
          }
          sum += value;
        }
      }
      image.at<uint8_t>(y, x) = static_cast<uint8_t>(sum / 4);
    }
  }
  return image;
}

TEST(BoardSpec, ParseAndValidate) {
  auto board = ParseBoardSize("9x6", 25);
  ASSERT_TRUE(board);
  EXPECT_EQ(board->cols, 9);
  EXPECT_EQ(board->rows, 6);
  EXPECT_EQ(board->Validate(), "");
  EXPECT_FALSE(ParseBoardSize("9-6", 25));
  board->square_mm = 0;
  EXPECT_EQ(board->Validate(), "BoardSpec.square_mm = 0: must be > 0");
}

TEST(CalibrateIntrinsics, RecoversSyntheticCameraWithDistortion) {
  const geometry::CameraModel truth = TruthCamera();
  const BoardSpec board{9, 6, 20.0};
  struct Pose {
    double rx, ry, rz, tx, ty, tz;
  };
  const Pose poses[] = {{0.0, 0.0, 0.0, 0, 0, 330},       {0.35, 0.0, 0.1, -20, 10, 360},
                        {-0.35, 0.1, -0.1, 15, -10, 350}, {0.0, 0.4, 0.2, 30, 0, 370},
                        {0.1, -0.4, -0.2, -30, 15, 360},  {0.3, 0.3, 0.5, 0, 20, 400},
                        {-0.3, -0.3, -0.4, 10, -20, 380}, {0.2, -0.2, 1.2, 0, 0, 420}};
  std::vector<std::vector<cv::Point2f>> views;
  for (const Pose& pose : poses) {
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(pose.rz, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(pose.ry, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(pose.rx, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    const cv::Mat image = RenderBoard(truth, board, R, Eigen::Vector3d(pose.tx, pose.ty, pose.tz));
    auto corners = DetectChessboard(image, board);
    ASSERT_TRUE(corners) << "board not found in synthetic view " << views.size();
    views.push_back(*corners);
  }
  const IntrinsicsResult result = CalibrateIntrinsics(views, board, cv::Size(640, 480));
  ASSERT_TRUE(result.ok) << result.message;
  EXPECT_LT(result.rms_px, 0.15);
  ASSERT_EQ(result.per_view_rms_px.size(), views.size());
  EXPECT_NEAR(result.camera.fx, truth.fx, 0.005 * truth.fx);
  EXPECT_NEAR(result.camera.fy, truth.fy, 0.005 * truth.fy);
  EXPECT_NEAR(result.camera.cx, truth.cx, 1.5);
  EXPECT_NEAR(result.camera.cy, truth.cy, 1.5);
  EXPECT_NEAR(result.camera.distortion[0], truth.distortion[0], 0.04);  // k1 trades off with k2, k3
  // The recovered model reprojects like the truth over the image (what the solver relies on).
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(-80, -60, 400), Eigen::Vector3d(90, 70, 420)}) {
    const Eigen::Vector2d a = *truth.Project(p);
    const Eigen::Vector2d b = *result.camera.Project(p);
    EXPECT_LT((a - b).norm(), 1.0);
  }
}

TEST(CalibrateIntrinsics, RefusesTooFewViews) {
  const IntrinsicsResult result = CalibrateIntrinsics({}, BoardSpec{}, cv::Size(640, 480));
  EXPECT_FALSE(result.ok);
  EXPECT_NE(result.message.find("at least 3 views"), std::string::npos);
}

// Debian's opencv-doc ships left01..14.jpg (no left10), possibly gzip-compressed.
cv::Mat ReadSample(const std::filesystem::path& dir, const std::string& name) {
  const auto plain = dir / name;
  if (std::filesystem::exists(plain)) return cv::imread(plain.string(), cv::IMREAD_GRAYSCALE);
  const auto gz = dir / (name + ".gz");
  if (!std::filesystem::exists(gz)) return {};
  const std::string command = "gzip -dc '" + gz.string() + "'";
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return {};
  std::vector<uint8_t> bytes;
  uint8_t chunk[65536];
  size_t got;
  while ((got = std::fread(chunk, 1, sizeof(chunk), pipe)) > 0) {
    bytes.insert(bytes.end(), chunk, chunk + got);
  }
  ::pclose(pipe);
  return cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
}

TEST(CalibrateIntrinsics, OpenCvSampleChessboardPhotos) {
  const std::filesystem::path dir = "/usr/share/doc/opencv-doc/examples/data";
  const BoardSpec board{9, 6, 25.0};
  std::vector<std::vector<cv::Point2f>> views;
  cv::Size size;
  int present = 0;
  for (int i = 1; i <= 14; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "left%02d.jpg", i);
    cv::Mat image = ReadSample(dir, name);
    if (image.empty()) continue;
    ++present;
    size = image.size();
    if (auto corners = DetectChessboard(image, board)) views.push_back(*corners);
  }
  if (present == 0) GTEST_SKIP() << dir << ": left*.jpg absent (install Debian's opencv-doc)";
  EXPECT_EQ(present, 13);
  EXPECT_GE(views.size(), 12u);
  const IntrinsicsResult result = CalibrateIntrinsics(views, board, size);
  ASSERT_TRUE(result.ok) << result.message;
  // OpenCV's own result for this set (left_intrinsics.yml, aspect ratio fixed): f = 535.9,
  // c = (342.3, 235.6). A free calibration agrees to a few pixels.
  EXPECT_LT(result.rms_px, 0.5);
  EXPECT_NEAR(result.camera.fx, 535.9, 10);
  EXPECT_NEAR(result.camera.fy, 535.9, 10);
  EXPECT_NEAR(result.camera.cx, 342.3, 10);
  EXPECT_NEAR(result.camera.cy, 235.6, 10);
}

}  // namespace
}  // namespace msmcal::calib

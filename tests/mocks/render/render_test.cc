// Tests of the rig simulator's image renderer: sub-pixel honesty of edges and dots against the
// projected truth, canonical colouring, occlusion, determinism, formats and validation.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <random>
#include <thread>

#include "common/units.h"
#include "mocks/render/ray_map.h"
#include "mocks/render/renderer.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::render {
namespace {

using geometry::CameraModel;
using geometry::Rigid3d;

CameraModel DistortedCamera(int w = 1600, int h = 1200) {
  CameraModel cam;
  cam.width = w;
  cam.height = h;
  cam.fx = 1500.0 * w / 1600;
  cam.fy = 1502.0 * w / 1600;
  cam.cx = 0.5 * (w - 1) + 3.3;
  cam.cy = 0.5 * (h - 1) - 2.1;
  cam.distortion = {-0.22, 0.09, 0.0012, -0.0008, -0.01};
  return cam;
}

CameraModel PinholeCamera() {
  CameraModel cam;
  cam.width = 200;
  cam.height = 200;
  cam.fx = cam.fy = 1000;
  cam.cx = cam.cy = 100;
  return cam;
}

RenderOptions NoiseFree(PixelFormat format = PixelFormat::kMono8) {
  RenderOptions opt;
  opt.format = format;
  opt.noise_sigma = 0;
  opt.shot_noise = 0;
  return opt;
}

// Board whose centre (between the inner corners) sits at `centre_in_cam`, rotated by
// Rz(in_plane) * R(axis, tilt): tilt 0 faces the camera with the printed side.
SceneBoard PlaceBoard(const BoardSpec& spec, const Eigen::Vector3d& centre_in_cam, double tilt_deg,
                      const Eigen::Vector3d& tilt_axis, double in_plane_deg) {
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(tilt_deg * common::kRadPerDeg, tilt_axis.normalized()).toRotationMatrix() *
      Eigen::AngleAxisd(in_plane_deg * common::kRadPerDeg, Eigen::Vector3d::UnitZ())
          .toRotationMatrix();
  const Eigen::Vector3d centre_in_board(0.5 * (spec.cols - 1) * spec.square_mm,
                                        0.5 * (spec.rows - 1) * spec.square_mm, 0);
  return SceneBoard{spec, Rigid3d(r, centre_in_cam - r * centre_in_board)};
}

Eigen::Vector2d ProjectBoardPoint(const CameraModel& cam, const SceneBoard& b, double x_mm,
                                  double y_mm) {
  return *cam.Project(b.cam_from_board * Eigen::Vector3d(x_mm, y_mm, 0));
}

double PixelLevel(const cv::Mat& img, const Eigen::Vector2d& px, int channel = 0) {
  const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
  switch (img.type()) {
    case CV_8UC1:
      return img.at<uint8_t>(y, x) / 255.0;
    case CV_16UC1:
      return img.at<uint16_t>(y, x) / 65535.0;
    case CV_8UC3:
      return img.at<cv::Vec3b>(y, x)[channel] / 255.0;
  }
  return -1;
}

struct CornerStats {
  double max_px = 0, rms_px = 0;
  int n = 0;
};

// Refines every inner corner with cornerSubPix started at the projected truth +-1 px and
// compares with the projected truth.
CornerStats RefineCorners(const CameraModel& cam, const SceneBoard& board, const cv::Mat& img) {
  cv::Mat grey;
  if (img.type() == CV_8UC3)
    cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  else if (img.type() == CV_16UC1)
    img.convertTo(grey, CV_32F, 1.0 / 257);
  else
    grey = img;
  const BoardSpec& s = board.spec;
  std::vector<Eigen::Vector2d> truth;
  double min_side = 1e9;
  for (int r = 0; r < s.rows; ++r)
    for (int c = 0; c < s.cols; ++c) {
      const Eigen::Vector2d p = ProjectBoardPoint(cam, board, c * s.square_mm, r * s.square_mm);
      truth.push_back(p);
      for (const auto& [dc, dr] :
           {std::pair{1, 0}, std::pair{0, 1}, std::pair{-1, 0}, std::pair{0, -1}})
        min_side = std::min(
            min_side,
            (ProjectBoardPoint(cam, board, (c + dc) * s.square_mm, (r + dr) * s.square_mm) - p)
                .norm());
    }
  const int win = std::clamp(static_cast<int>(min_side / 3), 2, 6);
  std::vector<cv::Point2f> pts;
  for (size_t k = 0; k < truth.size(); ++k) {
    const float ox = (k % 2 == 0) ? 1.0f : -1.0f, oy = (k % 3 == 0) ? -1.0f : 1.0f;
    pts.emplace_back(static_cast<float>(truth[k].x()) + ox, static_cast<float>(truth[k].y()) + oy);
  }
  cv::cornerSubPix(grey, pts, cv::Size(win, win), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 100, 1e-5));
  CornerStats st;
  double sum2 = 0;
  for (size_t k = 0; k < truth.size(); ++k) {
    const double e = (Eigen::Vector2d(pts[k].x, pts[k].y) - truth[k]).norm();
    st.max_px = std::max(st.max_px, e);
    sum2 += e * e;
  }
  st.n = static_cast<int>(truth.size());
  st.rms_px = std::sqrt(sum2 / st.n);
  return st;
}

std::vector<SceneBoard> CornerPoses() {
  const BoardSpec spec{9, 6, 25.0, 1.0};
  return {
      PlaceBoard(spec, {0, 0, 520}, 0, Eigen::Vector3d::UnitX(), 0),
      PlaceBoard(spec, {170, 110, 620}, 45, Eigen::Vector3d::UnitY(), 0),
      PlaceBoard(spec, {-60, 30, 480}, 55, Eigen::Vector3d::UnitX(), 20),
      PlaceBoard(spec, {40, -50, 470}, 60, Eigen::Vector3d(1, 1, 0), -35),
      PlaceBoard(spec, {-150, -120, 700}, 40, Eigen::Vector3d(1, -2, 0), 170),
  };
}

TEST(RayMapTest, MatchesIterativeUndistortAndIsCached) {
  const CameraModel cam = DistortedCamera(640, 480);
  const auto map = CachedRayMap(cam);
  EXPECT_EQ(map.get(), CachedRayMap(cam).get());
  EXPECT_LT(map->max_residual(), 1e-10);
  std::mt19937 rng(3);
  for (int k = 0; k < 500; ++k) {
    const int x = static_cast<int>(rng() % cam.width), y = static_cast<int>(rng() % cam.height);
    const Eigen::Vector2d expect = cam.Undistort(Eigen::Vector2d(x, y));
    EXPECT_LT((map->At(x, y) - expect).norm(), 2e-7) << x << "," << y;
  }
  CameraModel other = cam;
  other.distortion[0] += 1e-3;
  EXPECT_FALSE(map->Matches(other));
}

TEST(RenderTest, CornerSubPixWithinTenthOfPixel) {
  const CameraModel cam = DistortedCamera();
  double worst = 0;
  int pose = 0;
  for (const SceneBoard& board : CornerPoses()) {
    for (const bool noisy : {false, true}) {
      RenderOptions opt = noisy ? RenderOptions{} : NoiseFree();
      opt.seed = 17 + pose;
      RenderStats rs;
      const cv::Mat img = Render(cam, {board}, {}, opt, &rs);
      const CornerStats st = RefineCorners(cam, board, img);
      std::printf(
          "pose %d %s: %d corners, max %.4f px, rms %.4f px (edge px %lld, outline px %lld)\n",
          pose, noisy ? "noisy" : "clean", st.n, st.max_px, st.rms_px,
          static_cast<long long>(rs.edge_pixels), static_cast<long long>(rs.outline_pixels));
      EXPECT_LT(st.max_px, 0.1) << "pose " << pose << (noisy ? " noisy" : " clean");
      worst = std::max(worst, st.max_px);
    }
    ++pose;
  }
  RecordProperty("corner_max_error_px", std::to_string(worst));
}

TEST(RenderTest, EdgePositionsAreExactAreaAverages) {
  // Without PSF, a pixel row crossing one square edge holds exactly the dark area to the
  // edge's side: the sum of dark fractions over the row locates the edge where it crosses the
  // row's centre line (for an edge that is straight over the pixel band). This checks the
  // renderer itself, independently of any corner detector, with distortion and oblique views.
  const CameraModel cam = DistortedCamera();
  RenderOptions opt = NoiseFree(PixelFormat::kMono16);
  opt.blur_sigma_px = 0;
  double worst = 0;
  int n = 0;
  for (const SceneBoard& board : CornerPoses()) {
    const cv::Mat img = Render(cam, {board}, {}, opt);
    const BoardSpec& s = board.spec;
    for (int c = 0; c < s.cols; ++c)
      for (int r = -1; r < s.rows; ++r) {
        // The pixel row through the middle of the edge segment x = c, y in [r, r+1] (grid).
        const Eigen::Vector2d mid =
            ProjectBoardPoint(cam, board, c * s.square_mm, (r + 0.5) * s.square_mm);
        const int row = static_cast<int>(std::lround(mid.y()));
        // Board y on that line whose projection lies on the row's centre (bisection).
        double lo = r, hi = r + 1;
        const auto py = [&](double gy) {
          return ProjectBoardPoint(cam, board, c * s.square_mm, gy * s.square_mm).y();
        };
        if ((py(lo) - row) * (py(hi) - row) > 0) continue;
        for (int it = 0; it < 60; ++it) {
          const double m = 0.5 * (lo + hi);
          ((py(lo) - row) * (py(m) - row) <= 0 ? hi : lo) = m;
        }
        const double gy = 0.5 * (lo + hi);
        if (gy < r + 0.25 || gy > r + 0.75) continue;  // stay away from the corners
        const double edge_x = ProjectBoardPoint(cam, board, c * s.square_mm, gy * s.square_mm).x();
        // Only edges steep enough that the +-6 px window contains this edge alone.
        const Eigen::Vector2d dir =
            ProjectBoardPoint(cam, board, c * s.square_mm, (gy + 0.01) * s.square_mm) -
            ProjectBoardPoint(cam, board, c * s.square_mm, gy * s.square_mm);
        if (std::abs(dir.x()) > 0.5 * std::abs(dir.y())) continue;
        const int x0 = static_cast<int>(std::lround(edge_x)) - 6, x1 = x0 + 12;
        double dark = 0;
        for (int x = x0; x <= x1; ++x)
          dark += (img.at<uint16_t>(row, x) / 65535.0 - opt.board_white) /
                  (opt.board_black - opt.board_white);
        const bool dark_left = img.at<uint16_t>(row, x0) < img.at<uint16_t>(row, x1);
        const double est = dark_left ? x0 - 0.5 + dark : x1 + 0.5 - dark;
        worst = std::max(worst, std::abs(est - edge_x));
        ++n;
      }
  }
  std::printf("%d edge crossings: max |rendered - projected| = %.5f px\n", n, worst);
  EXPECT_GT(n, 100);
  EXPECT_LT(worst, 0.01);
}

TEST(RenderTest, CornersInMono16AndBgr) {
  const CameraModel cam = DistortedCamera();
  const SceneBoard board = CornerPoses()[3];
  for (const PixelFormat f : {PixelFormat::kMono16, PixelFormat::kBgr8}) {
    const cv::Mat img = Render(cam, {board}, {}, NoiseFree(f));
    ASSERT_EQ(img.type(), CvType(f));
    const CornerStats st = RefineCorners(cam, board, img);
    EXPECT_LT(st.max_px, 0.1) << ToString(f);
  }
}

TEST(RenderTest, AreaAverageClosedForm) {
  // Pinhole, frontal board at 1000 mm, fx 1000: 1 mm on the board = 1 px. The origin corner at
  // pixel (100.2, 100.0): the vertical line through it splits pixel column 100 into 0.7 of
  // square i=-1 (light for j=0) and 0.3 of square i=0 (dark for j=0).
  const CameraModel cam = PinholeCamera();
  const BoardSpec spec{5, 4, 10.0, 1.0};
  const SceneBoard board{spec, Rigid3d(Eigen::Matrix3d::Identity(), {0.2, 0, 1000})};
  RenderOptions opt = NoiseFree(PixelFormat::kMono16);
  opt.blur_sigma_px = 0;  // the exact area average
  RenderStats rs;
  const cv::Mat img = Render(cam, {board}, {}, opt, &rs);
  const double w = opt.board_white, b = opt.board_black;
  EXPECT_NEAR(img.at<uint16_t>(105, 100) / 65535.0, w + (b - w) * 0.3, 1.0 / 65535);
  EXPECT_NEAR(img.at<uint16_t>(105, 101) / 65535.0, b, 0.5 / 65535);  // inside (0, 0): dark
  EXPECT_NEAR(img.at<uint16_t>(105, 99) / 65535.0, w, 0.5 / 65535);   // inside (-1, 0): light
  // Pixel (100, 100) is split 0.7/0.3 horizontally and 0.5/0.5 vertically between the four
  // squares around the origin corner; (-1,-1) and (0,0) are dark: 0.7*0.5 + 0.3*0.5 = 0.5.
  EXPECT_NEAR(img.at<uint16_t>(100, 100) / 65535.0, w + (b - w) * 0.5, 1.0 / 65535);
  // Only pixels along square edges are shaded analytically; most are flat.
  EXPECT_GT(rs.edge_pixels, 0);
  EXPECT_GT(rs.flat_pixels, 20 * rs.edge_pixels);
  EXPECT_GT(rs.outline_pixels, 0);  // the board's outline against the background
}

TEST(RenderTest, CanonicalColouring) {
  const CameraModel cam = DistortedCamera(800, 600);
  const BoardSpec spec{7, 4, 20.0, 1.0};
  const RenderOptions opt = NoiseFree();
  for (const SceneBoard& board :
       {PlaceBoard(spec, {0, 0, 500}, 0, Eigen::Vector3d::UnitX(), 0),
        PlaceBoard(spec, {20, -10, 520}, 30, Eigen::Vector3d::UnitY(), 180),
        PlaceBoard(spec, {-20, 10, 500}, 35, Eigen::Vector3d(1, 1, 0), 90)}) {
    const cv::Mat img = Render(cam, {board}, {}, opt);
    const double s = spec.square_mm;
    const auto at = [&](double x, double y) {
      return PixelLevel(img, ProjectBoardPoint(cam, board, x * s, y * s));
    };
    const double tol = 1.0 / 255;
    EXPECT_NEAR(at(-0.5, -0.5), opt.board_black, tol);  // square (-1,-1): dark
    EXPECT_NEAR(at(0.5, -0.5), opt.board_white, tol);   // square (0,-1): light
    EXPECT_NEAR(at(-0.5, 0.5), opt.board_white, tol);   // square (-1,0): light
    EXPECT_NEAR(at(0.5, 0.5), opt.board_black, tol);    // square (0,0): dark
    EXPECT_NEAR(at(-1.5, 2.0), opt.board_white, tol);   // margin
    EXPECT_NEAR(at(spec.cols + 0.5, 1.0), opt.board_white, tol);
    // (cols+1) even, (rows+1) odd: the far corner's outward square (cols-1, rows-1) is dark
    // along the rows and light along the cols ends.
    EXPECT_NEAR(at(spec.cols - 0.5, -0.5), opt.board_white, tol);  // (cols-1, -1): light
    EXPECT_NEAR(at(-0.5, spec.rows - 0.5), opt.board_black, tol);  // (-1, rows-1): dark
    EXPECT_NEAR(at(-3.0, -3.0), opt.ambient, tol);                 // beyond the print
  }
  EXPECT_EQ(BoardLevelAt(spec, -5, -5, opt), opt.board_black);
  EXPECT_EQ(BoardLevelAt(spec, 5, -5, opt), opt.board_white);
  EXPECT_FALSE(BoardLevelAt(spec, -50, 0, opt).has_value());
}

TEST(RenderTest, GrazingAndCameraStraddlingBoardsStayInRange) {
  // A huge board whose plane passes next to the camera (rays graze it; part of it lies behind
  // the camera) and a board seen at 88 degrees: footprints become huge and degenerate.
  const CameraModel cam = DistortedCamera(320, 240);
  const BoardSpec huge{51, 40, 20.0, 1.0};
  // Printed side up, 60 mm below the camera, X = -x_C, Y = +z_C: from 320 mm behind the
  // camera to 520 mm in front of it.
  Eigen::Matrix3d floor_rot;
  floor_rot.col(0) = -Eigen::Vector3d::UnitX();
  floor_rot.col(1) = Eigen::Vector3d::UnitZ();
  floor_rot.col(2) = Eigen::Vector3d::UnitY();
  const SceneBoard floor{huge, Rigid3d(floor_rot, Eigen::Vector3d(500, 60, -300))};
  const SceneBoard grazing =
      PlaceBoard({9, 6, 25.0, 1.0}, {0, -20, 600}, 88, Eigen::Vector3d::UnitY(), 0);
  RenderOptions opt = NoiseFree(PixelFormat::kMono16);
  RenderStats rs;
  const cv::Mat img = Render(cam, {floor, grazing}, {}, opt, &rs);
  double lo, hi;
  cv::minMaxLoc(img, &lo, &hi);
  EXPECT_GE(lo, std::floor(std::min({opt.ambient, opt.board_black, opt.board_back}) * 65535) - 1);
  EXPECT_LE(hi, std::ceil(std::max({opt.ambient, opt.board_white, opt.board_back}) * 65535) + 1);
  EXPECT_GT(rs.edge_pixels, 0);
  EXPECT_GT(rs.outline_pixels, 0);
  // The lower image rows see the floor's printed squares: both levels appear there.
  const cv::Mat lower = img.rowRange(cam.height * 3 / 4, cam.height);
  cv::minMaxLoc(lower, &lo, &hi);
  EXPECT_LT(lo, (opt.board_black + 0.05) * 65535);
  EXPECT_GT(hi, (opt.board_white - 0.05) * 65535);
}

TEST(RenderTest, BoardSeenFromBehindIsUniform) {
  const CameraModel cam = DistortedCamera(640, 480);
  const BoardSpec spec{7, 4, 20.0, 1.0};
  // Rotated 180 degrees about Y: Z points to the camera, the camera sees the unprinted side.
  const SceneBoard board = PlaceBoard(spec, {0, 0, 500}, 180, Eigen::Vector3d::UnitY(), 0);
  const RenderOptions opt = NoiseFree();
  const cv::Mat img = Render(cam, {board}, {}, opt);
  for (double x = -0.5; x < spec.cols; x += 1.0)
    EXPECT_NEAR(PixelLevel(img, ProjectBoardPoint(cam, board, x * spec.square_mm, 10)),
                opt.board_back, 1.0 / 255);
}

TEST(RenderTest, NearerBoardOccludesFartherOne) {
  const CameraModel cam = DistortedCamera(800, 600);
  const SceneBoard far_board =
      PlaceBoard({11, 8, 40.0, 1.0}, {10, 5, 1500}, 10, Eigen::Vector3d::UnitY(), 0);
  const SceneBoard near_board =
      PlaceBoard({5, 4, 20.0, 1.0}, {-5, 0, 700}, 25, Eigen::Vector3d(1, 1, 0), 7);
  const RenderOptions opt = NoiseFree();
  const cv::Mat both = Render(cam, {far_board, near_board}, {}, opt);
  const cv::Mat swapped = Render(cam, {near_board, far_board}, {}, opt);
  EXPECT_EQ(cv::norm(both, swapped, cv::NORM_INF), 0.0) << "board order must not matter";
  const cv::Mat far_only = Render(cam, {far_board}, {}, opt);

  int differing = 0;
  const BoardSpec& ns = near_board.spec;
  for (int j = -1; j < ns.rows; ++j)
    for (int i = -1; i < ns.cols; ++i) {
      const Eigen::Vector3d p =
          near_board.cam_from_board *
          Eigen::Vector3d((i + 0.5) * ns.square_mm, (j + 0.5) * ns.square_mm, 0);
      const Eigen::Vector2d px = *cam.Project(p);
      const double near_level =
          *BoardLevelAt(ns, (i + 0.5) * ns.square_mm, (j + 0.5) * ns.square_mm, opt);
      EXPECT_NEAR(PixelLevel(both, px), near_level, 1.0 / 255) << i << "," << j;
      if (std::abs(PixelLevel(far_only, px) - near_level) > 0.3) ++differing;
    }
  EXPECT_GT(differing, 3) << "the test must probe pixels where the far board differs";
  // Outside the near board the far board shows through unchanged.
  const Eigen::Vector2d outside = ProjectBoardPoint(cam, far_board, 9.5 * 40, 6.5 * 40);
  EXPECT_EQ(PixelLevel(both, outside), PixelLevel(far_only, outside));
}

struct Centroid {
  Eigen::Vector2d c;
  Eigen::Matrix2d cov;
};

// Background-subtracted intensity-weighted centroid and second moments over a square window.
Centroid MeasureDot(const cv::Mat& img, const Eigen::Vector2d& centre, int radius, int channel) {
  const int x0 = static_cast<int>(std::lround(centre.x())) - radius;
  const int y0 = static_cast<int>(std::lround(centre.y())) - radius;
  const int n = 2 * radius + 1;
  const auto value = [&](int x, int y) {
    if (img.type() == CV_16UC1) return static_cast<double>(img.at<uint16_t>(y, x));
    if (img.type() == CV_8UC3) return static_cast<double>(img.at<cv::Vec3b>(y, x)[channel]);
    return static_cast<double>(img.at<uint8_t>(y, x));
  };
  std::vector<double> border;
  for (int k = 0; k < n; ++k) {
    border.push_back(value(x0 + k, y0));
    border.push_back(value(x0 + k, y0 + n - 1));
    border.push_back(value(x0, y0 + k));
    border.push_back(value(x0 + n - 1, y0 + k));
  }
  double bg = 0;  // mean of the window's border: unbiased under noise
  for (double b : border) bg += b / border.size();
  double sw = 0;
  Eigen::Vector2d s1 = Eigen::Vector2d::Zero();
  Eigen::Matrix2d s2 = Eigen::Matrix2d::Zero();
  for (int y = y0; y < y0 + n; ++y)
    for (int x = x0; x < x0 + n; ++x) {
      const double wgt = value(x, y) - bg;
      const Eigen::Vector2d p(x, y);
      sw += wgt;
      s1 += wgt * p;
      s2 += wgt * p * p.transpose();
    }
  Centroid c;
  c.c = s1 / sw;
  c.cov = s2 / sw - c.c * c.c.transpose();
  return c;
}

std::vector<SceneDot> TestDots() {
  std::vector<SceneDot> dots;
  const Eigen::Vector3d normals[] = {{0, 0, 0}, {0.8, 0, -0.6}, {0.3, -0.7, -0.5}, {0, 1, -1}};
  const double peaks[] = {0.7, 0.4, 3.0, 0.9};
  int k = 0;
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.3, -0.7, 500), Eigen::Vector3d(-180, -120, 520),
        Eigen::Vector3d(170, 110, 480), Eigen::Vector3d(-150, 115, 505),
        Eigen::Vector3d(60, 90, 450), Eigen::Vector3d(-90, 20, 600)}) {
    SceneDot d;
    d.p_in_cam = p;
    d.sigma_mm = 0.5 + 0.1 * k;
    d.normal_in_cam = normals[k % 4];
    d.peak = peaks[k % 4];
    dots.push_back(d);
    ++k;
  }
  return dots;
}

TEST(RenderTest, DotCentroidsWithinFiveHundredthsOfPixel) {
  const CameraModel cam = DistortedCamera(640, 480);
  for (const PixelFormat f : {PixelFormat::kMono8, PixelFormat::kMono16, PixelFormat::kBgr8}) {
    RenderOptions opt = NoiseFree(f);
    opt.ambient = 0.1;
    RenderStats rs;
    const std::vector<SceneDot> dots = TestDots();
    const cv::Mat img = Render(cam, {}, dots, opt, &rs);
    EXPECT_EQ(rs.dots_drawn, static_cast<int>(dots.size()));
    double worst = 0;
    for (const SceneDot& d : dots) {
      const ImageDot id = *ProjectDot(cam, d, opt);
      const double lam =
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(id.cov_px2).eigenvalues()(1);
      const int radius = static_cast<int>(std::ceil(std::sqrt(lam + 1.0 / 12) *
                                                    std::sqrt(2 * std::log(id.peak * 4 * 65535)))) +
                         2;
      const Centroid c = MeasureDot(img, id.centre_px, radius, /*channel=*/1);
      const double err = (c.c - id.centre_px).norm();
      worst = std::max(worst, err);
      EXPECT_LT(err, 0.05) << ToString(f) << " dot at " << id.centre_px.transpose();
      if (id.peak < 1 - opt.ambient && f == PixelFormat::kMono16) {  // unsaturated: shape too
        const Eigen::Matrix2d expect =
            id.cov_px2 +
            (1.0 / 12 + opt.blur_sigma_px * opt.blur_sigma_px) * Eigen::Matrix2d::Identity();
        EXPECT_LT((c.cov - expect).norm(), 0.05 * expect.norm()) << c.cov << "\nvs\n" << expect;
      }
    }
    std::printf("%s: worst dot centroid error %.4f px\n", ToString(f), worst);
  }
}

TEST(RenderTest, DotElongationAndColour) {
  const CameraModel cam = DistortedCamera(640, 480);
  RenderOptions opt = NoiseFree(PixelFormat::kBgr8);
  SceneDot d;
  d.p_in_cam = {0, 0, 500};
  d.sigma_mm = 1.0;
  d.normal_in_cam = {std::sin(std::numbers::pi / 3), 0,
                     -std::cos(std::numbers::pi / 3)};  // 60 degrees oblique
  const ImageDot id = *ProjectDot(cam, d, opt);
  const Eigen::Vector2d ev =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(id.cov_px2).eigenvalues();
  EXPECT_NEAR(std::sqrt(ev(1) / ev(0)), 2.0, 0.05);                    // 1 / cos(60 deg)
  EXPECT_NEAR(std::sqrt(id.cov_px2(1, 1)), cam.fy * 1.0 / 500, 0.01);  // the unforeshortened axis
  const cv::Mat img = Render(cam, {}, {d}, opt);
  const cv::Vec3b centre = img.at<cv::Vec3b>(static_cast<int>(std::lround(id.centre_px.y())),
                                             static_cast<int>(std::lround(id.centre_px.x())));
  EXPECT_GT(centre[1], centre[0] + 50);  // green dominates
  EXPECT_GT(centre[1], centre[2] + 50);
  EXPECT_GT(centre[0], std::lround(opt.ambient * 255));  // a little blue
}

TEST(RenderTest, NoisyDotCentroidIsUnbiased) {
  const CameraModel cam = DistortedCamera(640, 480);
  SceneDot d;
  d.p_in_cam = {7.3, -4.1, 400};
  d.sigma_mm = 1.0;
  RenderOptions opt;
  opt.format = PixelFormat::kMono16;
  opt.ambient = 0.1;
  const ImageDot id = *ProjectDot(cam, d, opt);
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  const int n = 20;
  for (int s = 0; s < n; ++s) {
    opt.seed = 1000 + s;
    const cv::Mat img = Render(cam, {}, {d}, opt);
    const Eigen::Vector2d c = MeasureDot(img, id.centre_px, 6, 0).c;
    EXPECT_LT((c - id.centre_px).norm(), 0.1) << "seed " << opt.seed;
    mean += c / n;
  }
  EXPECT_LT((mean - id.centre_px).norm(), 0.02);
}

TEST(RenderTest, SameSeedSameBytes) {
  const CameraModel cam = DistortedCamera(640, 480);
  const std::vector<SceneBoard> boards = {
      PlaceBoard({9, 6, 25.0, 1.0}, {0, 0, 900}, 20, Eigen::Vector3d::UnitY(), 0),
      PlaceBoard({5, 4, 15.0, 1.0}, {-20, 10, 500}, 35, Eigen::Vector3d::UnitX(), 5)};
  for (const PixelFormat f : {PixelFormat::kMono8, PixelFormat::kMono16, PixelFormat::kBgr8}) {
    RenderOptions opt;
    opt.format = f;
    opt.seed = 42;
    const cv::Mat a = Render(cam, boards, TestDots(), opt);
    const cv::Mat b = Render(cam, boards, TestDots(), opt);
    ASSERT_EQ(a.total() * a.elemSize(), b.total() * b.elemSize());
    EXPECT_EQ(std::memcmp(a.data, b.data, a.total() * a.elemSize()), 0) << ToString(f);
    opt.seed = 43;
    const cv::Mat c = Render(cam, boards, TestDots(), opt);
    EXPECT_NE(std::memcmp(a.data, c.data, a.total() * a.elemSize()), 0) << ToString(f);
  }
}

TEST(RenderTest, ConcurrentRendersMatchSerialOnes) {
  // Two threads render through the shared ray-map cache (one builds it, one may wait or build
  // it too); each result must equal the serial render with the same seed.
  CameraModel cam = DistortedCamera(480, 360);
  cam.distortion[4] = 0.003;  // a camera no other test uses: the cache starts cold
  const std::vector<SceneBoard> boards = {
      PlaceBoard({9, 6, 25.0, 1.0}, {0, 0, 900}, 20, Eigen::Vector3d::UnitY(), 0)};
  RenderOptions a, b;
  a.seed = 1;
  b.seed = 2;
  b.format = PixelFormat::kBgr8;
  cv::Mat img_a, img_b;
  std::thread ta([&] { img_a = Render(cam, boards, TestDots(), a); });
  std::thread tb([&] { img_b = Render(cam, boards, TestDots(), b); });
  ta.join();
  tb.join();
  EXPECT_EQ(cv::norm(img_a, Render(cam, boards, TestDots(), a), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(img_b, Render(cam, boards, TestDots(), b), cv::NORM_INF), 0.0);
}

TEST(RenderTest, NoiseMatchesModel) {
  const CameraModel cam = DistortedCamera(400, 300);
  RenderOptions opt;
  opt.format = PixelFormat::kMono16;
  opt.ambient = 0.5;
  opt.noise_sigma = 0.01;
  opt.shot_noise = 0.02;
  const cv::Mat img = Render(cam, {}, {}, opt);
  cv::Scalar mean, stddev;
  cv::meanStdDev(img, mean, stddev);
  const double expect = std::sqrt(0.01 * 0.01 + 0.02 * 0.02 * 0.5) * 65535;
  EXPECT_NEAR(mean[0], 0.5 * 65535, 0.01 * expect);
  EXPECT_NEAR(stddev[0], expect, 0.02 * expect);
}

TEST(RenderTest, FullRangeAndSaturation) {
  const CameraModel cam = DistortedCamera(640, 480);
  const BoardSpec spec{7, 4, 20.0, 1.0};
  const SceneBoard board = PlaceBoard(spec, {0, 0, 600}, 0, Eigen::Vector3d::UnitX(), 0);
  SceneDot dot;
  dot.p_in_cam = {250, 150, 600};  // off the board, on the ambient background
  dot.peak = 5.0;
  for (const PixelFormat f : {PixelFormat::kMono16, PixelFormat::kMono8}) {
    RenderOptions opt = NoiseFree(f);
    opt.ambient = 0.0;
    opt.board_black = 0.0;
    opt.board_white = 1.0;
    const cv::Mat img = Render(cam, {board}, {dot}, opt);
    const double full = f == PixelFormat::kMono16 ? 65535 : 255;
    double lo, hi;
    cv::minMaxLoc(img, &lo, &hi);
    EXPECT_EQ(lo, 0);
    EXPECT_EQ(hi, full);
    EXPECT_EQ(PixelLevel(img, ProjectBoardPoint(cam, board, 10, -10)), 1.0);   // white square
    EXPECT_EQ(PixelLevel(img, ProjectBoardPoint(cam, board, -10, -10)), 0.0);  // dark square
    EXPECT_EQ(PixelLevel(img, *cam.Project(dot.p_in_cam)), 1.0);               // saturated dot
  }
}

TEST(RenderTest, RendersIntoExternalBufferWithPadding) {
  const CameraModel cam = DistortedCamera(320, 240);
  const std::vector<SceneBoard> boards = {
      PlaceBoard({9, 6, 25.0, 1.0}, {0, 0, 900}, 20, Eigen::Vector3d::UnitY(), 0)};
  RenderOptions opt;
  opt.format = PixelFormat::kBgr8;
  opt.seed = 5;
  const size_t step = cam.width * 3 + 40;
  std::vector<uint8_t> buffer(step * cam.height, 0xAB);
  cv::Mat view(cam.height, cam.width, CV_8UC3, buffer.data(), step);
  std::vector<ImageDot> image_dots;
  for (const SceneDot& d : TestDots()) image_dots.push_back(*ProjectDot(cam, d, opt));
  RenderInto(cam, boards, image_dots, opt, view);
  EXPECT_EQ(view.data, buffer.data()) << "must not reallocate";
  const cv::Mat ref = Render(cam, boards, TestDots(), opt);
  EXPECT_EQ(cv::norm(view, ref, cv::NORM_INF), 0.0);
  for (int y = 0; y < cam.height; ++y)
    for (size_t k = cam.width * 3; k < step; ++k) ASSERT_EQ(buffer[y * step + k], 0xAB);

  cv::Mat wrong(cam.height, cam.width, CV_8UC1);
  EXPECT_THROW(RenderInto(cam, boards, image_dots, opt, wrong), std::invalid_argument);
}

TEST(RenderTest, ValidationMessagesNameFieldValueAndConstraint) {
  RenderOptions opt;
  EXPECT_EQ(opt.Validate(), "");
  opt.noise_sigma = -1;
  EXPECT_EQ(opt.Validate(), "RenderOptions.noise_sigma = -1 violates 0 <= noise_sigma < inf");
  opt = RenderOptions{};
  opt.board_white = 1.5;
  EXPECT_EQ(opt.Validate(), "RenderOptions.board_white = 1.5 violates 0 <= board_white <= 1");
  opt = RenderOptions{};
  opt.outline_supersampling = 0;
  EXPECT_NE(opt.Validate().find("outline_supersampling = 0"), std::string::npos);
  opt = RenderOptions{};
  opt.dot_sigma_px = 0;
  EXPECT_NE(opt.Validate().find("dot_sigma_px"), std::string::npos);

  BoardSpec spec;
  spec.square_mm = -2;
  EXPECT_EQ(spec.Validate(), "BoardSpec.square_mm = -2 violates 0 < square_mm < inf");

  const CameraModel cam = DistortedCamera(64, 48);
  opt = RenderOptions{};
  opt.shot_noise = -0.5;
  try {
    Render(cam, {}, {}, opt);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("shot_noise = -0.5"), std::string::npos) << e.what();
  }
  try {
    Render(cam, {SceneBoard{spec, Rigid3d()}}, {}, RenderOptions{});
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("boards[0]: BoardSpec.square_mm"), std::string::npos)
        << e.what();
  }
  ImageDot bad;
  bad.cov_px2 << 1, 0, 0, -4;
  cv::Mat out(cam.height, cam.width, CV_8UC1);
  EXPECT_THROW(RenderInto(cam, {}, std::vector<ImageDot>{bad}, RenderOptions{}, out),
               std::invalid_argument);
  CameraModel bad_cam = cam;
  bad_cam.fx = 0;
  EXPECT_THROW(Render(bad_cam, {}, {}, RenderOptions{}), std::invalid_argument);
}

}  // namespace
}  // namespace msmcal::render

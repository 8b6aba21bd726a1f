#pragma once
// The mirror-pose estimation problem of the MSM paper Sec. V-A as plain data: what was measured
// (corners, sliding-plane dots, reflected dots, each with its pixel covariance) and the unknowns
// (camera-from-board transforms, incident beams, mirror planes), all in {W} unless named.
//
// Frames: {C1} camera in step 1, {C2} camera in step 2 (each fixed during its step), {W} world
// board, {S_l} the sliding board at pose l. Board frames follow interchange-format.md (Z into
// the board, away from the camera). Lengths in mm, pixels with (0, 0) at the centre of the
// top-left pixel.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "processing/geometry/camera_model.h"
#include "processing/geometry/plane_line.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::solver {

struct PixelObs {
  Eigen::Vector2d px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov_px2 = Eigen::Matrix2d::Identity();  // 1-sigma covariance, px^2
};

enum class BoardView { kC1World, kC1Sliding, kC2World };

// One detected board in one image: its corner points in the board frame and their pixels.
struct CornerSet {
  BoardView view = BoardView::kC1World;
  int pose = -1;  // sliding pose index (0 .. num_poses-1) for kC1Sliding
  std::vector<Eigen::Vector3d> points_in_board;
  std::vector<Eigen::Vector2d> px;
};

struct SlidingDot {  // laser dot of beam `beam` on the sliding board at pose `pose` (C_L)
  int pose = 0;
  int beam = 0;
  PixelObs obs;
};

struct ReflectedDot {  // laser dot of beam `beam` reflected by mirror plane `plane` onto {W} (C_R)
  int plane = 0;
  int beam = 0;
  PixelObs obs;
  // The spot overlaps a square edge or corner of the board (after the top-hat, the background
  // there biases the centroid): its variance factor is estimated separately (mle.h).
  bool near_board_edge = false;
};

struct Observations {
  geometry::CameraModel camera;
  int num_poses = 0;   // sliding-plane poses
  int num_beams = 0;   // all beams with sliding dots (estimate and validate)
  int num_planes = 0;  // mirror planes (one per trigger index / neutral / fast-only sample)
  std::vector<CornerSet> corners;
  std::vector<SlidingDot> sliding_dots;
  std::vector<ReflectedDot> reflected_dots;  // fitted: only beams with role `estimate`
  double corner_sigma_px = 0.1;              // isotropic 1-sigma of a corner, px
};

struct Estimate {
  geometry::Rigid3d c1_from_world;
  geometry::Rigid3d c2_from_world;
  std::vector<geometry::Rigid3d> c1_from_sliding;  // per pose
  std::vector<geometry::Line> beams;               // in {W}, v from source towards the mirror
  std::vector<geometry::Plane> planes;             // in {W}, n towards the incoming beams
};

// Predicted pixel of a laser dot: beam reflected by `mirror` onto the world plane z = 0, seen by
// the camera at c2_from_world. Empty if the geometry does not produce a visible dot.
std::optional<Eigen::Vector2d> PredictReflectedDot(const geometry::CameraModel& camera,
                                                   const geometry::Rigid3d& c2_from_world,
                                                   const geometry::Line& beam_in_world,
                                                   const geometry::Plane& mirror_in_world);
// Point where the reflected beam meets the world plane, in {W}.
std::optional<Eigen::Vector3d> ReflectedPointOnWorld(const geometry::Line& beam_in_world,
                                                     const geometry::Plane& mirror_in_world);
// Predicted pixel of a beam's dot on the sliding board at c1_from_sliding.
std::optional<Eigen::Vector2d> PredictSlidingDot(const geometry::CameraModel& camera,
                                                 const geometry::Rigid3d& c1_from_world,
                                                 const geometry::Rigid3d& c1_from_sliding,
                                                 const geometry::Line& beam_in_world);
// Back-projection of a pixel onto the plane z = 0 of a board seen at cam_from_board, in the
// board frame (paper Sec. V-A1). Empty if the ray misses the plane.
std::optional<Eigen::Vector3d> BackProjectToBoard(const geometry::CameraModel& camera,
                                                  const geometry::Rigid3d& cam_from_board,
                                                  const Eigen::Vector2d& px);

// Orthonormal 3x2 basis of the plane perpendicular to unit vector n (deterministic).
Eigen::Matrix<double, 3, 2> TangentBasis(const Eigen::Vector3d& n);

}  // namespace msmcal::solver

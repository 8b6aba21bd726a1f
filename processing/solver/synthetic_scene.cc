#include "processing/solver/synthetic_scene.h"

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "common/units.h"

namespace msmcal::solver {
namespace {

using geometry::Line;
using geometry::Plane;
using geometry::Rigid3d;

// Camera at `centre` looking along `forward` with image x roughly along `right`.
Rigid3d LookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& forward,
               const Eigen::Vector3d& right_hint) {
  const Eigen::Vector3d z = forward.normalized();
  const Eigen::Vector3d x = (right_hint - right_hint.dot(z) * z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d world_from_cam;
  world_from_cam << x, y, z;
  return Rigid3d(world_from_cam, centre).Inverse();
}

}  // namespace

SyntheticScene MakeSyntheticScene(const SyntheticSceneOptions& o) {
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(-1.0, 1.0);
  SyntheticScene s;
  Observations& obs = s.obs;
  geometry::CameraModel& cam = obs.camera;
  cam.width = 2000;
  cam.height = 1600;
  cam.fx = cam.fy = 2400;
  cam.cx = 1000;
  cam.cy = 800;
  cam.distortion = {-0.05, 0.02, 0.0005, -0.0003, 0.0};
  obs.corner_sigma_px = o.corner_sigma_px;
  obs.num_poses = o.num_poses;
  obs.num_beams = static_cast<int>(o.beam_azimuth_deg.size());
  obs.num_planes = o.num_planes;

  const Eigen::Vector3d mirror_centre(70, 45, -200);
  s.rotation_centre_in_world = mirror_centre;
  Estimate& t = s.truth;
  t.c1_from_world = LookAt(Eigen::Vector3d(520, 45, -480), Eigen::Vector3d(-1, 0, 1),
                           Eigen::Vector3d(0, -1, 0).cross(Eigen::Vector3d(-1, 0, 1)));
  t.c2_from_world = LookAt(Eigen::Vector3d(75, 40, -450), Eigen::Vector3d(0.05, 0.02, 1),
                           Eigen::Vector3d(1, 0, 0));
  // Beams: aimed near the mirror centre (not exactly through it), from +X.
  for (int b = 0; b < obs.num_beams; ++b) {
    const double az = o.beam_azimuth_deg[b] * common::kRadPerDeg,
                 el = o.beam_elevation_deg[b] * common::kRadPerDeg;
    const Eigen::Vector3d v(-std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                            -std::sin(el));
    const Eigen::Vector3d miss(0, 0.4 * b - 0.3, 0.25 * b);
    t.beams.push_back(Line::FromPointDirection(mirror_centre + miss, v));
  }
  // Sliding boards: perpendicular to -X_W (Z along -X_W, into the board), 150..350 mm from the
  // mirror along the beams.
  for (int l = 0; l < o.num_poses; ++l) {
    const double x = mirror_centre.x() + 150 + 200.0 * l / std::max(1, o.num_poses - 1);
    Eigen::Matrix3d world_from_s;
    const Eigen::Vector3d z(-1, 0, 0), xs(0, 1, 0);
    world_from_s << xs, z.cross(xs), z;
    const Eigen::Matrix3d tilt = geometry::So3Exp(Eigen::Vector3d(0.05 * l, -0.03 * l, 0.02));
    const Rigid3d world_from_sliding(world_from_s * tilt, Eigen::Vector3d(x, -20, -240));
    t.c1_from_sliding.push_back(t.c1_from_world * world_from_sliding);
  }
  // Mirror planes: neutral normal bisecting -v0 and +Z_W, tilted about two axes, through a point
  // near the rotation centre.
  const Eigen::Vector3d n0 = (Eigen::Vector3d(0, 0, 1) - t.beams[0].v).normalized();
  const Eigen::Matrix<double, 3, 2> basis = TangentBasis(n0);
  for (int j = 0; j < o.num_planes; ++j) {
    const Eigen::Vector2d tilt(unif(rng), unif(rng));
    const Eigen::Vector3d n =
        (n0 + basis * (tilt * o.mirror_amplitude_deg * common::kRadPerDeg)).normalized();
    t.planes.push_back(Plane{n, n.dot(mirror_centre) + o.mirror_trans_mm * unif(rng)});
  }
  // Random dot covariance of about dot_sigma_px.
  auto random_cov = [&]() {
    const double a = o.dot_sigma_px * (0.7 + 0.6 * (unif(rng) * 0.5 + 0.5));
    const double bb = o.dot_sigma_px * (0.7 + 0.6 * (unif(rng) * 0.5 + 0.5));
    const double th = M_PI * unif(rng);
    Eigen::Matrix2d r;
    r << std::cos(th), -std::sin(th), std::sin(th), std::cos(th);
    return Eigen::Matrix2d(r * Eigen::Vector2d(a * a, bb * bb).asDiagonal() * r.transpose());
  };
  auto noisy = [&](const Eigen::Vector2d& px, const Eigen::Matrix2d& cov) {
    const Eigen::Matrix2d l = cov.llt().matrixL();
    return Eigen::Vector2d(px + l * Eigen::Vector2d(gauss(rng), gauss(rng)));
  };
  // Corners.
  auto add_board = [&](BoardView view, int pose, const Rigid3d& cam_from_board, int cols, int rows,
                       double square) {
    CornerSet cs;
    cs.view = view;
    cs.pose = pose;
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < cols; ++c) {
        const Eigen::Vector3d p(c * square, r * square, 0);
        const auto px = cam.Project(cam_from_board * p);
        if (!px) continue;
        cs.points_in_board.push_back(p);
        cs.px.push_back(*px + o.corner_sigma_px * Eigen::Vector2d(gauss(rng), gauss(rng)));
      }
    obs.corners.push_back(cs);
  };
  add_board(BoardView::kC1World, -1, t.c1_from_world, 15, 10, 10.0);
  add_board(BoardView::kC2World, -1, t.c2_from_world, 15, 10, 10.0);
  for (int l = 0; l < o.num_poses; ++l)
    add_board(BoardView::kC1Sliding, l, t.c1_from_sliding[l], 9, 6, 10.0);
  // Sliding dots for every beam.
  for (int l = 0; l < o.num_poses; ++l)
    for (int b = 0; b < obs.num_beams; ++b) {
      const auto px = PredictSlidingDot(cam, t.c1_from_world, t.c1_from_sliding[l], t.beams[b]);
      if (!px) continue;
      const Eigen::Matrix2d cov = random_cov();
      obs.sliding_dots.push_back(SlidingDot{l, b, PixelObs{noisy(*px, cov), cov}});
    }
  for (int b = 0; b < obs.num_beams; ++b)
    (b < o.num_estimate ? s.estimate_beams : s.validate_beams).push_back(b);
  for (int j = 0; j < o.num_planes; ++j)
    for (int b = 0; b < obs.num_beams; ++b) {
      const auto px = PredictReflectedDot(cam, t.c2_from_world, t.beams[b], t.planes[j]);
      if (!px) continue;
      const Eigen::Matrix2d cov = random_cov();
      const ReflectedDot dot{j, b, PixelObs{noisy(*px, cov), cov}};
      (b < o.num_estimate ? obs.reflected_dots : s.validation_dots).push_back(dot);
    }
  return s;
}

}  // namespace msmcal::solver

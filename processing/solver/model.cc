#include "processing/solver/model.h"

#include <cmath>

namespace msmcal::solver {

using geometry::Line;
using geometry::Plane;
using geometry::Rigid3d;

std::optional<Eigen::Vector3d> ReflectedPointOnWorld(const Line& beam, const Plane& mirror) {
  const auto reflected = geometry::ReflectedBeam(mirror, beam);
  if (!reflected) return std::nullopt;
  const Eigen::Vector3d h = reflected->ClosestPointToOrigin();
  const Eigen::Vector3d r = reflected->v;
  if (std::abs(r.z()) < 1e-12) return std::nullopt;
  return h + (-h.z() / r.z()) * r;
}

std::optional<Eigen::Vector2d> PredictReflectedDot(const geometry::CameraModel& camera,
                                                   const Rigid3d& c2_from_world, const Line& beam,
                                                   const Plane& mirror) {
  const auto x = ReflectedPointOnWorld(beam, mirror);
  if (!x) return std::nullopt;
  return camera.Project(c2_from_world * *x);
}

std::optional<Eigen::Vector2d> PredictSlidingDot(const geometry::CameraModel& camera,
                                                 const Rigid3d& c1_from_world,
                                                 const Rigid3d& c1_from_sliding, const Line& beam) {
  const Line in_sliding = geometry::TransformLine(c1_from_sliding.Inverse() * c1_from_world, beam);
  const auto x = geometry::IntersectLinePlane(in_sliding, Plane{Eigen::Vector3d::UnitZ(), 0.0});
  if (!x) return std::nullopt;
  return camera.Project(c1_from_sliding * *x);
}

std::optional<Eigen::Vector3d> BackProjectToBoard(const geometry::CameraModel& camera,
                                                  const Rigid3d& cam_from_board,
                                                  const Eigen::Vector2d& px) {
  const Rigid3d board_from_cam = cam_from_board.Inverse();
  const Eigen::Vector3d origin = board_from_cam.translation;
  const Eigen::Vector3d dir = board_from_cam.rotation * camera.Unproject(px);
  return geometry::IntersectRayPlane(origin, dir, Plane{Eigen::Vector3d::UnitZ(), 0.0});
}

Eigen::Matrix<double, 3, 2> TangentBasis(const Eigen::Vector3d& n) {
  Eigen::Matrix<double, 3, 2> b;
  b.col(0) = n.unitOrthogonal();
  b.col(1) = n.cross(b.col(0)).normalized();
  return b;
}

}  // namespace msmcal::solver

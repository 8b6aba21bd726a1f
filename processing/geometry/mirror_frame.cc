#include "processing/geometry/mirror_frame.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace msmcal::geometry {

Rigid3d MirrorHomeFrame(const Eigen::Vector3d& neutral_normal, const Eigen::Vector3d& fast_axis,
                        const Eigen::Vector3d& centre) {
  const Eigen::Vector3d z = neutral_normal.normalized();
  Eigen::Vector3d x = fast_axis - fast_axis.dot(z) * z;
  if (x.norm() < 1e-9)
    throw std::invalid_argument("MirrorHomeFrame: fast axis parallel to the normal");
  x.normalize();
  const double along_x = x.dot(Eigen::Vector3d::UnitX());
  if (std::abs(along_x) >= 0.1) {
    if (along_x < 0) x = -x;
  } else if (x.dot(Eigen::Vector3d::UnitY()) < 0) {
    x = -x;
  }
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  return Rigid3d(r, centre);
}

MirrorPose PoseFromPlane(const Plane& p) {
  MirrorPose pose;
  pose.alpha_rad = std::asin(std::clamp(-p.n.y(), -1.0, 1.0));
  pose.beta_rad = std::atan2(p.n.x(), p.n.z());
  pose.trans_mm = p.d;
  return pose;
}

Plane PlaneFromPose(const MirrorPose& pose) {
  const double ca = std::cos(pose.alpha_rad);
  return Plane{Eigen::Vector3d(ca * std::sin(pose.beta_rad), -std::sin(pose.alpha_rad),
                               ca * std::cos(pose.beta_rad)),
               pose.trans_mm};
}

MirrorPose PoseFromWorldPlane(const Rigid3d& world_from_mirror0, const Plane& plane_in_world) {
  return PoseFromPlane(TransformPlane(world_from_mirror0.Inverse(), plane_in_world));
}

Plane WorldPlaneFromPose(const Rigid3d& world_from_mirror0, const MirrorPose& pose) {
  return TransformPlane(world_from_mirror0, PlaneFromPose(pose));
}

Eigen::Vector3d RotationCentreFromPlanes(const std::vector<Plane>& planes) {
  if (planes.size() < 3) throw std::invalid_argument("RotationCentreFromPlanes: needs >= 3 planes");
  Eigen::MatrixXd a(planes.size(), 3);
  Eigen::VectorXd b(planes.size());
  for (size_t i = 0; i < planes.size(); ++i) {
    a.row(i) = planes[i].n.transpose();
    b(i) = planes[i].d;
  }
  return a.colPivHouseholderQr().solve(b);
}

Eigen::Vector3d FastAxisFromPlanes(const std::vector<Plane>& planes) {
  if (planes.size() < 2) throw std::invalid_argument("FastAxisFromPlanes: needs >= 2 planes");
  Eigen::MatrixXd a(planes.size(), 3);
  for (size_t i = 0; i < planes.size(); ++i) a.row(i) = planes[i].n.transpose();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  return svd.matrixV().col(2);
}

Eigen::Vector3d FastAxisWithNeutral(const Plane& neutral, const std::vector<Plane>& fast_only) {
  if (fast_only.size() == 1) return FastAxisFromPlanes({neutral, fast_only[0]});
  return FastAxisFromPlanes(fast_only);
}

}  // namespace msmcal::geometry

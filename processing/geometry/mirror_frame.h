#pragma once
// The mirror home frame {0} (MSM paper Sec. V-A3, interchange-format.md):
//   Z = neutral mirror normal n_M0 (reflective side),
//   X = fast axis e_F made orthogonal to Z, signed to have a positive component along {W}'s X
//       (if |e_F . X_W| < 0.1: along {W}'s Y),
//   Y = Z x X, origin = rotation centre X_O.
// A mirror plane in {0} with normal n and offset d gives
//   alpha = asin(-n_y) (fast-axis angle), beta = atan2(n_x, n_z) (slow-axis angle), trans = d.

#include <Eigen/Core>

#include "processing/geometry/plane_line.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::geometry {

// Mirror pose in {0}: angles in radians here, millimetres for trans.
struct MirrorPose {
  double alpha_rad = 0;
  double beta_rad = 0;
  double trans_mm = 0;
};

// Builds world_from_mirror0 from the neutral normal, the fast axis and the rotation centre, all
// in {W}. `fast_axis` need not be orthogonal to `neutral_normal` (its component along it is
// removed); the sign rule above is applied.
Rigid3d MirrorHomeFrame(const Eigen::Vector3d& neutral_normal_in_world,
                        const Eigen::Vector3d& fast_axis_in_world,
                        const Eigen::Vector3d& rotation_centre_in_world);

// Plane in {0} <-> pose. PoseFromPlane requires n_z > 0 side conventions only through atan2.
MirrorPose PoseFromPlane(const Plane& plane_in_mirror0);
Plane PlaneFromPose(const MirrorPose& pose);

// Convenience: a mirror plane in {W} to its pose, given world_from_mirror0.
MirrorPose PoseFromWorldPlane(const Rigid3d& world_from_mirror0, const Plane& plane_in_world);
Plane WorldPlaneFromPose(const Rigid3d& world_from_mirror0, const MirrorPose& pose);

// Least-squares rotation centre X_O from mirror planes: min sum (n_j . X - d_j)^2 (eq. 11).
// Needs planes whose normals span R^3.
Eigen::Vector3d RotationCentreFromPlanes(const std::vector<Plane>& planes_in_world);

// Fast axis e_F as the direction orthogonal to all fast-only normals (smallest singular vector
// of the stacked normals), unsigned.
// The fast axis from the fast-only planes (FastAxisFromPlanes); from a single fast-only plane,
// with the neutral plane: the neutral pose lies on the fast-only trajectory (the fast axis at
// zero), so its normal is perpendicular to the axis too. Needs at least one fast-only plane.
Eigen::Vector3d FastAxisWithNeutral(const Plane& neutral, const std::vector<Plane>& fast_only);
Eigen::Vector3d FastAxisFromPlanes(const std::vector<Plane>& fast_only_planes_in_world);

}  // namespace msmcal::geometry

#pragma once
// The mirror home frame {0} as msmcal defines it (interchange-format.md; MSM paper Sec. V-A3,
// eq. 11), and the same construction applied to ground truth so that poses can be compared
// with a simulator's truth in one convention (docs/solver.md, "Mirror home frame").
//
// Convention: Z = neutral normal n_M0, X = fast axis e_F (MirrorHomeFrame's sign rule), origin
// X_O = the point of the NEUTRAL plane that is closest, in least squares, to the scan planes
// (eq. 11, Pi_M^T X_O = 0, with the neutral plane as a hard constraint). So the neutral pose is
// (alpha, beta, trans) = (0, 0, 0) by definition (drives off = home), and any part of the
// out-of-plane translation that is linear in the normal's in-plane components (e.g. trans
// proportional to beta) is absorbed into X_O's in-plane position: planes alone cannot tell it
// from a shifted rotation centre.

#include <Eigen/Core>
#include <vector>

#include "processing/geometry/plane_line.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::solver {

// X_O on `neutral` closest in least squares to `planes` (all in {W}). Directions that the
// planes do not constrain (fewer than two normals tilted from the neutral one) fall back to the
// point of `neutral` closest to the {W} origin.
Eigen::Vector3d HomeOrigin(const geometry::Plane& neutral,
                           const std::vector<geometry::Plane>& planes);

// world_from_mirror0 with the convention above.
geometry::Rigid3d HomeFrame(const geometry::Plane& neutral, const Eigen::Vector3d& fast_axis,
                            const std::vector<geometry::Plane>& scan_planes);

// Ground truth in the same convention: keeps the true frame's rotation (its Z is the true
// neutral normal, its X the true fast axis) and its origin's neutral plane, and moves the
// origin within that plane as HomeOrigin does for `true_scan_planes` (the true planes of the
// same trigger indices the estimate has). Compare poses as
//   PoseFromWorldPlane(ConventionalTruthFrame(truth, planes), true_plane).
geometry::Rigid3d ConventionalTruthFrame(const geometry::Rigid3d& world_from_mirror0_truth,
                                         const std::vector<geometry::Plane>& true_scan_planes);

}  // namespace msmcal::solver

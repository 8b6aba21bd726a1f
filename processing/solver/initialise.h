#pragma once
// Closed-form initial values (MSM paper Sec. V-A1, V-A2) and the baseline model of Table I.

#include <optional>
#include <string>
#include <vector>

#include "processing/solver/model.h"

namespace msmcal::solver {

// cam_from_board from planar correspondences (OpenCV IPPE, then iterative refinement with the
// full distortion model). Empty when PnP fails or needs more than 4 points.
std::optional<geometry::Rigid3d> SolvePlanarPnP(const geometry::CameraModel& camera,
                                                const std::vector<Eigen::Vector3d>& points_in_board,
                                                const std::vector<Eigen::Vector2d>& px);

// Incident beam from its dots in {W} (PCA, eq. 2), oriented so that it travels into the
// sliding board (v . z_S > 0 with z_S the sliding boards' mean Z axis in {W}).
geometry::Line FitBeam(const std::vector<Eigen::Vector3d>& dots_in_world,
                       const Eigen::Vector3d& sliding_z_in_world);

// Mirror plane from incident beams and their reflected dots on {W} (eq. 3): the normal is the
// smallest singular vector of the light-path normals n_Li = v_i x (X_i - p_i), oriented against
// the beams (n . v < 0); the offset is the least-squares d for which the virtual points
// X_i' = X_i - 2 (n.X_i - d) n lie on the beams. Needs >= 2 beams with non-parallel light-path
// planes; empty otherwise.
std::optional<geometry::Plane> InitialMirrorPlane(
    const std::vector<geometry::Line>& beams, const std::vector<Eigen::Vector3d>& dots_in_world);

// Initial estimate of everything from the observations: per-view PnP (shared transforms from
// the view with most corners), dots back-projected to {W}, beams by PCA, planes by
// InitialMirrorPlane. On failure returns empty and sets *error to what is missing.
std::optional<Estimate> InitialEstimate(const Observations& obs, std::string* error);

// Baseline model of Table I (the paper's ref. [26]): the mirror rotates purely about a centre
// that every incident beam passes through. The centre is the least-squares point closest to
// all `estimate` beams; each plane passes through it with the normal that best bisects
// (-v_i, r_i), r_i the unit direction from the centre to the reflected dot X_i of beam i.
struct BaselineModel {
  Eigen::Vector3d centre_in_world = Eigen::Vector3d::Zero();
  std::vector<geometry::Plane> planes;  // index = plane index; planes without dots keep n=z,d=0
};
BaselineModel FitBaseline(const std::vector<geometry::Line>& beams,
                          const std::vector<int>& estimate_beams,
                          const std::vector<ReflectedDot>& reflected, int num_planes,
                          const geometry::CameraModel& camera,
                          const geometry::Rigid3d& c2_from_world);

// Point closest (least squares) to a set of lines.
Eigen::Vector3d ClosestPointToLines(const std::vector<geometry::Line>& lines);

}  // namespace msmcal::solver

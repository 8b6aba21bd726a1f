#pragma once
// Maximum-likelihood refinement of all transforms, beams and mirror planes (MSM paper eqs. 4-7)
// with Ceres (Levenberg-Marquardt, DENSE_SCHUR with the mirror planes eliminated first), and
// the per-plane covariance of eq. 8 recovered through the Schur complement.
//
// Parameterisation (all Euclidean charts around a reference, so covariances need no manifold
// conversions; see docs/solver.md):
//   transform: [w (rad, 3), dt (mm, 3)]: cam_from_board = (Exp(w) R0, t0 + dt)
//   beam:      [a, b (rad), c, e (mm)]: v = normalize(v0 + U (a, b)), p = p0 + U (c, e), U =
//              TangentBasis(v0)
//   plane:     [a, b (rad), c (mm)]: n = normalize(n0 + B (a, b)), d = d0 + c, B = TangentBasis(n0)
// After the solve the charts are re-centred on the solution, so a plane's covariance is that of
// (B^T dn, dd) with B = TangentBasis(n): two small rotations of the normal (rad) and the offset.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <string>
#include <vector>

#include "processing/solver/model.h"

namespace msmcal::solver {

struct MleOptions {
  int max_iterations = 100;
  // Rescale corner and (pooled) dot covariances by their posterior variance factors
  // (chi^2 / dof of each family) and solve again, so that the reported covariance matches the
  // observed scatter.
  bool estimate_variance_factors = true;
  int num_threads = 1;
  std::string Validate() const;
};

struct MleResult {
  bool usable = false;  // false: Ceres failed or the information matrix is singular
  std::string message;  // Ceres's termination message or what failed
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;
  double solver_time_s = 0;  // as reported by Ceres
  // Posterior variance factors (chi^2 / dof) of each residual family relative to the input
  // covariances; with estimate_variance_factors the reported covariances include them.
  double corner_variance_factor = 1, dot_variance_factor = 1;
  Estimate estimate;
  // Per-plane 3x3 covariance of (B^T dn [rad, rad], dd [mm]), B = TangentBasis(plane.n).
  std::vector<Eigen::Matrix3d> plane_cov;
  // Covariance of the shared ("other") parameters, ordered: c1_from_world (6), c2_from_world
  // (6), c1_from_sliding[l] (6 each), beams[b] (4 each), in their re-centred charts.
  Eigen::MatrixXd other_cov;
  // Cross term: plane j vs others = -plane_gain[j]^T other_cov (3 x num_other).
  Eigen::SparseMatrix<double> plane_gain;  // num_other x 3 * num_planes
  int OffsetC2() const { return 6; }
  int OffsetBeam(int b) const { return 12 + 6 * num_poses + 4 * b; }
  int num_poses = 0;
  // Joint covariance of [plane j (3), others] (3 + num_other square).
  Eigen::MatrixXd JointCovariance(int plane) const;
};

// Refines `initial`. Residuals: corners with isotropic obs.corner_sigma_px, dots whitened by
// their 2x2 covariance.
MleResult SolveMle(const Observations& obs, const Estimate& initial,
                   const MleOptions& options = {});

// Chart maps in double precision (as used by the residuals), for propagating covariances.
geometry::Plane PlaneFromChart(const geometry::Plane& reference, const Eigen::Vector3d& x);
geometry::Line BeamFromChart(const geometry::Line& reference, const Eigen::Vector4d& x);
geometry::Rigid3d TransformFromChart(const geometry::Rigid3d& reference,
                                     const Eigen::Matrix<double, 6, 1>& x);
// Chart coordinates of `plane` around `reference` (inverse of PlaneFromChart).
Eigen::Vector3d PlaneToChart(const geometry::Plane& reference, const geometry::Plane& plane);

}  // namespace msmcal::solver

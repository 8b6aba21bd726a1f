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
#include <array>
#include <string>
#include <vector>

#include "processing/solver/model.h"

namespace msmcal::solver {

// Residual families with their own variance factor (variance-component estimation).
enum MleFamily {
  kCornersC1World = 0,     // world-board corners seen by C1 (step 1)
  kCornersC1Sliding,       // sliding-board corners (step 1)
  kCornersC2World,         // world-board corners seen by C2 (step 2)
  kSlidingDots,            // C_L: beam dots on the sliding board
  kReflectedDots,          // C_R: reflected dots on the world board, clear of square edges
  kReflectedDotsNearEdge,  // C_R: reflected dots overlapping a square edge or corner
  kNumFamilies
};
const char* MleFamilyName(int family);  // "corners_c1_world", ..., "reflected_dots"

struct MleOptions {
  int max_iterations = 100;
  // Variance-component estimation: each family's input covariance is rescaled by its posterior
  // variance factor chi^2_f / r_f, r_f = n_f - (sum of the family's leverages) its redundancy,
  // and the problem is solved again, `variance_passes` times; the reported covariance uses the
  // final factors, so that it matches the observed scatter of every family.
  bool estimate_variance_factors = true;
  int variance_passes = 3;
  int num_threads = 1;
  std::string Validate() const;
};

struct MleResult {
  bool usable = false;  // false: Ceres failed or the information matrix is singular
  std::string message;  // Ceres's termination message or what failed
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;
  double solver_time_s = 0;  // as reported by Ceres
  // Posterior variance factors (chi^2_f / r_f) of each residual family relative to the input
  // covariances, from the last pass; with estimate_variance_factors the reported covariances
  // use `covariance_scale` (the factors of the pass before, equal to them at convergence).
  std::array<double, kNumFamilies> variance_factor{1, 1, 1, 1, 1, 1};
  std::array<double, kNumFamilies> covariance_scale{1, 1, 1, 1, 1, 1};
  std::array<double, kNumFamilies> redundancy{}, family_chi2{};
  // Shorthands: variance_factor[kCornersC2World] and variance_factor[kReflectedDots].
  double corner_variance_factor = 1, dot_variance_factor = 1;
  Estimate estimate;
  // Per-plane 3x3 covariance of (B^T dn [rad, rad], dd [mm]), B = TangentBasis(plane.n).
  std::vector<Eigen::Matrix3d> plane_cov;
  // Its own part H_jj^-1 (the plane's dots alone, shared parameters fixed). Planes are
  // independent given the shared parameters o: x_j = own_j - G_j^T o with G = plane_gain,
  // so Cov(x_j, x_k) = G_j^T other_cov G_k for j != k.
  std::vector<Eigen::Matrix3d> plane_own_cov;
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
  // Beam b's direction sigma in {W} as an RMS angle, rad (DirectionSigmaRad of its direction
  // block; summary.json beam_direction_sigma_deg); NaN when other_cov does not hold beam b.
  double BeamDirectionSigmaRad(int b) const;
};

// The RMS angle (rad) of a direction whose two chart coordinates are angles: sqrt of the trace of
// their 2x2 covariance (negative rounding clamped to 0). A plane's normal: the top-left block of
// its chart covariance (summary.json rms_sigma_normal_world_deg); a beam's: BeamDirectionSigmaRad.
double DirectionSigmaRad(const Eigen::Matrix2d& cov);

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

#pragma once
// Ellipsoid fit and compensation (MARG paper Sec. 2.2, eqs. 4-19).
//
// A triaxial sensor (magnetometer, accelerometer) with hard-iron offset and soft-iron / scale /
// cross-axis distortion measures, over all orientations, points on an ellipsoid
//   (x - c)^T W (x - c) = 1,  W symmetric positive definite.
// Compensation maps it back to a sphere of radius r: y = r * A (x - c) with A = W^(1/2) =
// R diag(1/semi-axes) R^T: rotate into the principal axes (R^T), scale each axis, rotate back
// (R) -- the paper's "rotate, adjust the gains, multiply by the inverse of the DCM".
//
// Fit: the algebraic quadric (eq. 4) with Li & Griffiths' ellipsoid-specific constraint on
// centred and scaled data, then a geometric (radial) refinement by Levenberg-Marquardt of the
// residual |A (x - c)| - 1, with iterative MAD-based outlier rejection. Units are those of the
// samples (uT, g); nothing here does I/O.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace msmcal::marg {

// The paper's algebraic form (eq. 4):
//   A x^2 + B y^2 + C z^2 + D xy + E yz + F xz + G x + H y + J z + K = 0.
// D, E, F are the full cross-term coefficients (twice the off-diagonal entries of the quadric
// matrix); G, H, J likewise twice the linear entries.
struct QuadricCoefficients {
  double A = 0, B = 0, C = 0, D = 0, E = 0, F = 0, G = 0, H = 0, J = 0, K = 0;
};

// The paper's 4x4 matrix form S (eq. 8) with X S X^T = 0 for X = [x y z 1].
Eigen::Matrix4d QuadricMatrix(const QuadricCoefficients& q);

// Value of eq. 4 at x.
double EvaluateQuadric(const QuadricCoefficients& q, const Eigen::Vector3d& x);

struct Ellipsoid {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  // W of (x - c)^T W (x - c) = 1: the canonical form's matrix of eq. 13 ([a d e; d b f; e f c]).
  Eigen::Matrix3d shape = Eigen::Matrix3d::Identity();
  // Eigen-analysis (eqs. 16-20): W = R diag(lambda) R^T, columns of `axes` = R (a proper rotation,
  // det +1), semi_axes_i = 1 / sqrt(lambda_i), ascending lambda (descending semi-axes).
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d semi_axes = Eigen::Vector3d::Ones();

  // A = W^(1/2) = R diag(1/semi_axes) R^T: maps the ellipsoid onto the unit sphere.
  Eigen::Matrix3d UnitSphereMap() const;
  // Geometric mean of the semi-axes (radius of the sphere of equal volume).
  double MeanRadius() const;
  // |A (x - c)| - 1: radial distance of x from the surface in units of the ellipsoid's scale.
  double RadialResidual(const Eigen::Vector3d& x) const;
  // Builds centre/shape/axes/semi_axes from a centre and an SPD shape matrix. Returns false if
  // the shape is not positive definite.
  static bool FromCentreShape(const Eigen::Vector3d& centre, const Eigen::Matrix3d& shape,
                              Ellipsoid* out);
};

// Centre, canonical form and eigen-analysis of a quadric (eqs. 9-18). Returns false, with a
// reason in *why, if the quadric is not a real ellipsoid (the 3x3 part is not definite, or the
// canonical constant has the wrong sign).
bool EllipsoidFromQuadric(const QuadricCoefficients& q, Ellipsoid* out, std::string* why);

// The quadric of an ellipsoid, normalised to K = -1 (inverse of the above).
QuadricCoefficients QuadricFromEllipsoid(const Ellipsoid& e);

struct EllipsoidFitOptions {
  int min_samples = 20;
  // Samples whose radial residual exceeds outlier_sigmas * robust sigma (1.4826 * MAD) are
  // rejected; the fit is repeated up to max_outlier_rounds times. 0 rounds: no rejection.
  double outlier_sigmas = 4.0;
  int max_outlier_rounds = 4;
  // The robust sigma is floored at this fraction of the radius so that noise-free data does not
  // reject round-off.
  double min_relative_sigma = 1e-9;
  // Geometric refinement (Levenberg-Marquardt).
  bool refine = true;
  int max_iterations = 50;
  // A fit whose normal matrix (in normalised coordinates) has a condition number above this is
  // reported degenerate: the samples do not constrain all 9 parameters.
  double max_condition = 1e8;
  // A fit whose radial residual spread (relative to the radius; robust 1.4826 x median |r| before
  // outlier rejection, RMS over the inliers after it) exceeds this is reported as not an
  // ellipsoid: the samples lie on some other surface (or the sensor moved while sampling).
  double max_rms_residual = 0.1;

  // "" if valid, else "field=value violates constraint".
  std::string Validate() const;
};

enum class EllipsoidFitStatus {
  kOk,
  kTooFewSamples,  // fewer than min_samples (after outlier rejection)
  kDegenerate,     // samples on a plane/line or too small a patch: parameters not determined
  kNotEllipsoid,   // best quadric is not an ellipsoid (hyperboloid, paraboloid, ...)
  kNonFinite,      // NaN/inf in the samples
};
const char* ToString(EllipsoidFitStatus status);

struct EllipsoidFitResult {
  EllipsoidFitStatus status = EllipsoidFitStatus::kDegenerate;
  std::string message;            // says what happened, with the figures
  Ellipsoid ellipsoid;            // final (refined) fit, valid if status == kOk
  QuadricCoefficients algebraic;  // Li-Griffiths fit in the samples' units (K = -1 scale)
  Ellipsoid algebraic_ellipsoid;  // the algebraic fit before refinement
  std::vector<bool> inlier;       // one per sample
  int num_inliers = 0;
  double rms_radial_residual = 0;  // RMS of |A(x-c)| - 1 over inliers (relative units)
  double condition_number = 0;     // of the refinement's normal matrix, normalised coords
  int iterations = 0;

  bool ok() const { return status == EllipsoidFitStatus::kOk; }
};

// Algebraic fit only (Li & Griffiths 2004, k = 4) on the samples as given (callers normalise;
// FitEllipsoid does). Returns false with a reason if no ellipsoid solution exists.
bool FitQuadricLiGriffiths(const std::vector<Eigen::Vector3d>& samples, QuadricCoefficients* out,
                           std::string* why);

// The full fit: normalise (centre on the mean, scale by the RMS distance), algebraic fit,
// denormalise, geometric refinement, outlier rejection. Never throws on bad data: the status
// says what happened. Throws std::invalid_argument only for invalid options.
EllipsoidFitResult FitEllipsoid(const std::vector<Eigen::Vector3d>& samples,
                                const EllipsoidFitOptions& options = {});

}  // namespace msmcal::marg

#pragma once
// Sensor-plane alignment (MARG paper Sec. 2.1, eqs. 1-3).
//
// While the board's XY plane stays on a fixed plane and the board turns about its Z axis, a
// fixed physical vector (gravity, the Earth's field) traces, in each sensor's frame, a circle
// whose plane is normal to the board's Z axis as seen by that sensor. Fitting that plane and
// rotating its normal onto (0, 0, 1) aligns the sensor's XY plane with the board's. The rotation
// about Z (yaw) is not observable this way.
//
// Interpretation: the paper fits z = alpha x + beta y + gamma by ordinary least squares (eq. 1).
// We fit the plane by total least squares (PCA of the circle's points), which is unbiased when
// every axis is noisy and works for any tilt, and report the same alpha, beta, gamma. The
// normal's sign is chosen with a positive z component (the paper's (-alpha, -beta, 1), eq. 2).
// The alignment is R_y(eps_pitch) R_x(eps_roll) (eq. 3): first about x, then about y.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace msmcal::marg {

struct PlaneAlignmentOptions {
  int min_samples = 10;
  // The circle's radius relative to its distance from the origin must exceed this: a vector
  // parallel to the rotation axis traces no circle (e.g. gravity on a level plane).
  double min_relative_radius = 0.02;
  // Required angular coverage of the circle (the paper asks for at least one full turn).
  double min_turn_deg = 300.0;
  std::string Validate() const;  // "" if valid
};

enum class PlaneAlignmentStatus { kOk, kTooFewSamples, kNoCircle, kPartialTurn, kNonFinite };
const char* ToString(PlaneAlignmentStatus status);

struct PlaneAlignmentResult {
  PlaneAlignmentStatus status = PlaneAlignmentStatus::kNoCircle;
  std::string message;
  double alpha = 0, beta = 0, gamma = 0;                    // z = alpha x + beta y + gamma
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();        // unit, n_z >= 0
  double roll_rad = 0;                                      // eps_roll, about x
  double pitch_rad = 0;                                     // eps_pitch, about y
  Eigen::Matrix3d alignment = Eigen::Matrix3d::Identity();  // maps normal onto (0,0,1)
  Eigen::Vector3d circle_centre = Eigen::Vector3d::Zero();
  double circle_radius = 0;
  double rms_plane_residual = 0;  // out-of-plane RMS, sample units
  double turn_deg = 0;            // angular coverage of the circle (360 = a full turn)
  bool ok() const { return status == PlaneAlignmentStatus::kOk; }
};

// The eq. 3 matrix R_y(pitch) R_x(roll).
Eigen::Matrix3d AlignmentMatrix(double roll_rad, double pitch_rad);
// Roll and pitch such that AlignmentMatrix(roll, pitch) * normal is along +z.
void AlignmentAngles(const Eigen::Vector3d& normal, double* roll_rad, double* pitch_rad);

// Fits the plane of the circle traced by `samples` and the alignment that levels it. Never
// throws for bad data (status says what happened); throws std::invalid_argument for invalid
// options.
PlaneAlignmentResult FitPlaneAlignment(const std::vector<Eigen::Vector3d>& samples,
                                       const PlaneAlignmentOptions& options = {});

}  // namespace msmcal::marg

#pragma once
// MARG / magnetometer calibration (MARG paper Sec. 2): per sensor an offset, a compensation
// matrix (ellipsoid -> sphere, Sec. 2.2) and an alignment matrix (sensor XY plane -> board XY
// plane, Sec. 2.1):
//   calibrated = alignment * compensation * (raw - offset).
// Order: the ellipsoid is fitted to the free-rotation recording; the plane alignment is fitted
// to the *compensated* plane-rotation recording (a circle only after compensation), which is
// the paper's "aligned-compensated" data.
//
// Accelerometer (g) and magnetometer (uT) get all three; the gyroscope (dps) gets an offset
// (median over the free-rotation recording, where the board is held still), an identity
// compensation (its gain is not observable without a reference rate) and an alignment that
// turns its mean rate axis during the plane rotation onto +z. A magnetometer-only recording
// (the Hall sensor) calibrates the magnetometer alone.
//
// Yaw about the board's Z axis is not observable by the plane method: each sensor keeps its own
// unknown heading offset.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/marg/coverage.h"
#include "processing/marg/ellipsoid.h"
#include "processing/marg/plane_alignment.h"

namespace msmcal::marg {

enum class Sensor { kAccelerometer, kGyroscope, kMagnetometer };
const char* ToString(Sensor sensor);  // "accelerometer" | "gyroscope" | "magnetometer"

// Which corrections to apply (MARG Table 1's three rows).
enum class Stage { kRaw, kCompensated, kAlignedCompensated };
const char* ToString(Stage stage);  // "raw" | "compensated" | "aligned_compensated"

struct SensorCalibration {
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  Eigen::Matrix3d compensation = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d alignment = Eigen::Matrix3d::Identity();

  // Figures (for the report and the YAML; not used by Apply).
  Ellipsoid ellipsoid;                // fitted raw ellipsoid (absent for the gyroscope)
  double sphere_radius = 0;           // norm of the compensated vectors (1 g, or |B| in uT)
  double ellipsoid_rms_residual = 0;  // relative radial RMS on the free-rotation inliers
  int ellipsoid_inliers = 0;
  int ellipsoid_samples = 0;
  double ellipsoid_condition = 0;
  double coverage = 0;  // sphere coverage of the free-rotation recording
  double alignment_roll_deg = 0;
  double alignment_pitch_deg = 0;
  double plane_rms_residual = 0;  // out-of-plane RMS of the compensated circle, sensor units
  double plane_turn_deg = 0;
  double norm_relative_std = 0;  // std/mean of |calibrated| over the free-rotation inliers

  Eigen::Vector3d Apply(const Eigen::Vector3d& raw, Stage stage = Stage::kAlignedCompensated) const;
};

struct MargCalibration {
  std::optional<SensorCalibration> accelerometer;
  std::optional<SensorCalibration> gyroscope;
  std::optional<SensorCalibration> magnetometer;
};

struct MargCalibrationOptions {
  EllipsoidFitOptions ellipsoid;
  PlaneAlignmentOptions plane;
  CoverageOptions coverage;
  // Fail when the free-rotation recording covers less of the sphere than this.
  double min_coverage = 0.5;
  double accelerometer_norm_g = 1.0;  // radius of the compensated accelerometer sphere
  // Radius of the compensated magnetometer sphere; 0: the fitted ellipsoid's mean radius.
  double magnetometer_norm_uT = 0.0;
  bool calibrate_gyroscope = true;
  // Plane-rotation samples with a bias-free rate below this are ignored for the gyro alignment.
  double gyro_min_rate_dps = 5.0;

  std::string Validate() const;  // "" if valid; else "field=value violates constraint"
};

struct MargCalibrationResult {
  bool ok = false;
  std::string message;                // what failed (sensor, step, reason) or a summary
  std::vector<std::string> warnings;  // e.g. the gyroscope could not be aligned
  MargCalibration calibration;
  // Where coverage was too low: unit directions (sensor frame) still missing.
  std::vector<Eigen::Vector3d> missing_directions;
};

// Calibrates from the plane-rotation and free-rotation recordings. Expected failures (too few
// samples, degenerate ellipsoid, no circle, poor coverage) give ok = false and a message naming
// the sensor and the step; invalid options throw std::invalid_argument.
MargCalibrationResult CalibrateMarg(const dataset::MargRecording& plane_rotation,
                                    const dataset::MargRecording& free_rotation,
                                    const MargCalibrationOptions& options = {});

// Same columns, same rows, same order; sensors without a calibration pass through unchanged.
dataset::MargRecording ApplyCalibration(const MargCalibration& calibration,
                                        const dataset::MargRecording& recording,
                                        Stage stage = Stage::kAlignedCompensated);

// Column access helpers.
Eigen::Vector3d Accel(const dataset::MargSample& s);
Eigen::Vector3d Gyro(const dataset::MargSample& s);
Eigen::Vector3d Mag(const dataset::MargSample& s);

struct AttitudeRow {
  double t_s = 0;
  double roll_deg = 0, pitch_deg = 0, yaw_deg = 0;
  double cost = 0;  // Gauss-Newton cost F at the solution
};

// Gauss-Newton attitude per sample (accelerometer + magnetometer columns required). The
// magnetic reference elevation is the recording's median asin(a^.m^) unless given. Each
// sample starts from the previous solution (TRIAD for the first). Throws std::invalid_argument
// for a magnetometer-only recording.
std::vector<AttitudeRow> SolveAttitudeSeries(const dataset::MargRecording& recording,
                                             std::optional<double> field_elevation_rad = {});

double MeanCost(const std::vector<AttitudeRow>& rows);

// Direction accuracy against truth: RMS angle (degrees) between measured and true directions
// after removing the single best rotation about z (the yaw the plane method cannot observe).
struct DirectionError {
  double rms_deg = 0;
  double max_deg = 0;
  double yaw_removed_deg = 0;
};
DirectionError CompareDirections(const std::vector<Eigen::Vector3d>& measured,
                                 const std::vector<Eigen::Vector3d>& truth, bool remove_yaw);

}  // namespace msmcal::marg

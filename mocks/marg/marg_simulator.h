#pragma once
// Simulated MARG board (accelerometer, gyroscope, magnetometer) with known distortions, for the
// calibration of the MARG paper; also the magnetometer-only variant (the triaxial Hall sensor).
//
// Sensor model, per sensor s, for the true vector v_board in the board frame:
//   raw = gain * sensor_from_board * v_board + offset + noise,   noise ~ N(0, noise_std^2 I)
// where sensor_from_board = Exp(misalignment) is the sensor's mounting rotation (its yaw part
// is not observable by the plane method), `gain` holds scale factors, cross-axis coupling and,
// for the magnetometer, soft iron; `offset` is the bias / hard iron.
// Earth frame: z up, x magnetic north. Accelerometer: specific force, +gravity_g along up.
// Gyroscope: body angular rate in dps. Magnetometer: field_uT with elevation
// field_elevation_deg (negative: pointing down).
//
// Recordings (interchange format's marg/): plane_rotation (board on a fixed plane inclined by
// plane_tilt_deg, turned about its Z axis), free_rotation (held still in uniformly random
// orientations), validation (another inclined plane, turned about Z). Deterministic in the seed.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"

namespace msmcal::sim {

struct SensorDistortion {
  Eigen::Vector3d misalignment_deg = Eigen::Vector3d::Zero();  // rotation vector, degrees
  Eigen::Matrix3d gain = Eigen::Matrix3d::Identity();
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  double noise_std = 0;

  Eigen::Matrix3d SensorFromBoard() const;
  // raw for a true board-frame vector, without noise.
  Eigen::Vector3d Distort(const Eigen::Vector3d& v_board) const;
};

struct MargSimConfig {
  double sample_rate_hz = 100;
  double gravity_g = 1.0;
  double field_uT = 48.0;
  double field_elevation_deg = -60.0;
  SensorDistortion accelerometer = DefaultAccelerometer();
  SensorDistortion gyroscope = DefaultGyroscope();
  SensorDistortion magnetometer = DefaultMagnetometer();

  // plane_rotation: fixed plane tilted by tilt about the horizontal axis at azimuth.
  double plane_tilt_deg = 25;
  double plane_tilt_azimuth_deg = 30;
  double plane_turns = 1.25;
  double plane_duration_s = 12;
  // free_rotation: held still in orientations (uniform on SO(3)).
  int free_orientations = 300;
  int free_samples_per_orientation = 4;
  // Fraction of free_rotation magnetometer samples replaced by spikes (outliers) of magnitude
  // outlier_magnitude * field_uT in a random direction.
  double outlier_fraction = 0;
  double outlier_magnitude = 0.6;
  // validation.
  double validation_tilt_deg = 15;
  double validation_tilt_azimuth_deg = 120;
  double validation_turns = 1.0;
  double validation_duration_s = 10;
  // The Hall sensor: recordings hold only t_s and the magnetometer columns.
  bool magnetometer_only = false;

  static SensorDistortion DefaultAccelerometer();
  static SensorDistortion DefaultGyroscope();
  static SensorDistortion DefaultMagnetometer();
  // "" if valid, else "field=value violates constraint".
  std::string Validate() const;
};

struct MargRecordingTruth {
  std::vector<Eigen::Quaterniond> earth_from_board;  // one per sample
  std::vector<Eigen::Vector3d> rate_board_dps;       // true body rate, one per sample
  std::vector<bool> outlier;                         // magnetometer spike injected
};

struct MargTruth {
  MargSimConfig config;  // distortions, field, motions
  uint64_t seed = 0;
  Eigen::Vector3d gravity_in_earth = Eigen::Vector3d::UnitZ();  // specific force, g
  Eigen::Vector3d field_in_earth = Eigen::Vector3d::UnitX();    // uT
  MargRecordingTruth plane_rotation, free_rotation, validation;

  // True board-frame vectors for one recording (specific force in g, field in uT).
  std::vector<Eigen::Vector3d> GravityInBoard(const MargRecordingTruth& rec) const;
  std::vector<Eigen::Vector3d> FieldInBoard(const MargRecordingTruth& rec) const;
};

struct MargSimulation {
  dataset::MargRecording plane_rotation, free_rotation, validation;
  MargTruth truth;
};

// Throws std::invalid_argument naming the field if the config is invalid.
MargSimulation SimulateMarg(const MargSimConfig& config, uint64_t seed);

// Writes dir/truth/marg.yaml: seed, field, per-sensor distortions, and per recording the true
// orientations (earth_from_board quaternions [w, x, y, z]) and outlier flags of every sample.
// Creates dir/truth. Throws std::runtime_error naming the file on failure.
void WriteMargTruth(const std::filesystem::path& dir, const MargTruth& truth);

}  // namespace msmcal::sim

#pragma once
// In-memory model of a recorded calibration session: everything the interchange format
// (../shared/docs/interchange-format.md, version 1) carries, as value types. Pure data: reading
// and writing folders lives in sessions/interchange; images are referenced by file name and
// loaded by whoever needs the pixels.
//
// Units: millimetres, degrees, seconds unless a field name says otherwise (_us, _uT, _rad).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "processing/geometry/camera_model.h"
#include "processing/geometry/plane_line.h"

namespace msmcal::dataset {

inline constexpr const char* kInterchangeFormat = "msmcal-interchange/1";

struct BoardSpec {
  int cols = 0;  // inner corners along X
  int rows = 0;  // inner corners along Y
  double square_mm = 0;
};

enum class BeamRole { kEstimate, kValidate };
const char* ToString(BeamRole role);  // "estimate" | "validate"

struct BeamSpec {
  int id = 0;
  BeamRole role = BeamRole::kEstimate;
};

struct DriveAxis {
  double frequency_hz = 0;
  double amplitude_vpp = 0;
  double phase_deg = 0;
};

struct Drive {
  DriveAxis fast;
  DriveAxis slow;
  double pattern_period_s = 0;
};

struct Trigger {
  int j = 0;
  double t_s = 0;  // pulse time within the pattern period
};

struct Step1Frame {
  std::string file;  // relative to the folder, e.g. "step1/0000.png"
  int pose = 0;      // sliding-plane pose index l
  std::vector<int> beams;
};

enum class Step2Kind { kNeutral, kFastOnly, kScan };
const char* ToString(Step2Kind kind);  // "neutral" | "fast_only" | "scan"

struct Step2Frame {
  std::string file;
  Step2Kind kind = Step2Kind::kScan;
  std::vector<int> triggers;  // empty for neutral frames
  std::vector<int> beams;
};

// MCU times are microseconds as decimal numbers: the interchange format allows a fraction
// ("8999999.609") and every reader keeps it (the MCU's own stream is whole microseconds).
struct HallReading {
  double mcu_time_us = 0;
  double bx_uT = 0, by_uT = 0, bz_uT = 0;
};

struct HallRecording {
  std::vector<HallReading> readings;
  std::vector<double> clock_edges_us;  // MCU time of each clock rising edge, ascending
};

struct MargSample {
  double t_s = 0;
  double ax_g = 0, ay_g = 0, az_g = 0;
  double gx_dps = 0, gy_dps = 0, gz_dps = 0;
  double mx_uT = 0, my_uT = 0, mz_uT = 0;
};

struct MargRecording {
  bool has_inertial = true;  // false: magnetometer-only columns t_s,mx_uT,my_uT,mz_uT
  std::vector<MargSample> samples;
};

// The whole folder except results/ and truth/.
struct Recording {
  std::string format = kInterchangeFormat;
  geometry::CameraModel camera;
  BoardSpec world_board;
  BoardSpec sliding_board;
  std::vector<BeamSpec> beams;
  Drive drive;
  double clock_frequency_hz = 0;
  std::vector<Trigger> triggers;
  std::vector<Step1Frame> step1;
  std::vector<Step2Frame> step2;
  std::optional<HallRecording> hall_actual;
  std::optional<HallRecording> hall_background;
  std::optional<MargRecording> marg_plane_rotation;
  std::optional<MargRecording> marg_free_rotation;
  std::optional<MargRecording> marg_validation;
};

// results/mirror_planes.csv, one row per trigger index of the scan frames.
struct MirrorPlaneRow {
  int j = 0;
  double t_s = 0;
  geometry::Plane plane_in_world;  // nx ny nz d_mm
  double alpha_deg = 0, beta_deg = 0, trans_mm = 0;
  double sigma_alpha_deg = 0, sigma_beta_deg = 0, sigma_trans_mm = 0;
};

// results/beams.csv: incident beam in {W}, point p and unit direction v (source -> mirror).
struct BeamRow {
  int beam = 0;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Vector3d v = Eigen::Vector3d::UnitZ();
};

// results/validation.csv.
struct ValidationRow {
  int beam = 0;
  int j = 0;
  double err_px = 0;
  double err_deg = 0;
};

}  // namespace msmcal::dataset

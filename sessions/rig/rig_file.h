#pragma once
// The lab's rig file (config/rig.yaml, docs/rig-file.md): one YAML file describing the rig — the
// two generators and the signals they play (`generators:`, drivers/generator/rig_config.h), the
// camera (`camera:`), the Hall MCU (`hall_mcu:`, drivers/hall_mcu/hall_mcu_config.h), the boards,
// the beams, the sliding plate's poses and the design knobs of step 1 and step 2 that
// `msmcal plan` turns into a session plan (sessions/plan).
//
// LoadRigFile reads and validates every field before anything is contacted: a refusal throws
// std::runtime_error "FILE:LINE: FIELD = VALUE: CONSTRAINT" (unknown keys and sections too, so a
// typo never falls back to a default silently). The generator and Hall MCU sections are read by
// their own loaders, so `msmcal gen --rig`, `hall record --rig` and `mock generators --rig` read
// the same file.

#include <filesystem>
#include <string>
#include <vector>

#include "drivers/generator/rig_config.h"
#include "drivers/hall_mcu/hall_mcu_config.h"
#include "processing/dataset/recording.h"
#include "processing/geometry/camera_model.h"

namespace msmcal::rig {

enum class CameraKind { kGige, kV4l2 };
const char* ToString(CameraKind kind);  // "gige" | "v4l2"

struct RigCamera {
  CameraKind kind = CameraKind::kGige;
  std::string address;          // kind gige: IP address (opened by address, never by discovery)
  std::string device;           // kind v4l2: device node, e.g. /dev/video0
  double frame_rate_hz = 10.0;  // free-run rate, (0, 1000]
  double exposure_us = 20000;   // (0, 1e7]; must fit in one frame period
  // Sensor size and nominal intrinsics (what the plan's camera.yaml holds; the solver refines
  // nothing of the camera: calibrate it first, e.g. with OpenCV, and write the result here).
  geometry::CameraModel model;
  // What InstrumentFactory::OpenCamera / camera::OpenCamera read: the address, or "v4l2:DEVICE".
  std::string OpenString() const;
  // The rig file's rule for another frame rate (a command line's --frame-rate): finite, in
  // (0, kMaxFrameRateHz] and its period at least exposure_us. "" or the violated constraint
  // ("must be in (0, 1000] Hz").
  std::string CheckFrameRate(double hz) const;
};
inline constexpr double kMaxFrameRateHz = 1000;

struct RigBeams {
  int count = 3;                  // 2 .. 16 beams from the splitter, ids 1..count
  std::vector<int> validate_ids;  // held out (role validate); at least 2 must estimate
};

// The sliding plate's poses in step 1 (as the simulator designs them, mocks/rig): `poses` poses
// evenly spaced from nearest_mm to farthest_mm from the mirror's position towards the source,
// tilted +tilt_deg / -tilt_deg alternately (pose 0: +tilt).
struct SlidingPlate {
  int poses = 7;  // 2 .. 50
  double nearest_mm = 35;
  double farthest_mm = 100;
  double tilt_deg = 12;  // [0, 60]
  // How far beside its printed pattern the plate may carry the spots, in squares ([0, 100]): the
  // quality gate counts a step 1 frame's dots within the pattern grown by this.
  double dot_margin_squares = 1.0;
  double DistanceMm(int pose) const;
  double TiltDeg(int pose) const;
};

struct Step1Design {
  int exposures = 3;                  // each step 1 frame taken this many times, 1 .. 20
  bool identification_frames = true;  // one single-beam frame per beam at the last pose
  bool background_frames = true;      // per pose, one frame with every beam blocked
};

struct Step2Design {
  int neutral_frames = 2;                // drives off, 0 .. 50
  int fast_only_frames = 3;              // slow drive off, 0 .. 50
  int fast_only_triggers_per_frame = 4;  // 1 .. 64
  int scan_triggers_per_frame = 3;       // at most, 1 .. 64
  // Separation rule inside one frame: no two triggers of a frame closer than this in signal
  // space (each drive normalised to [-1, 1], as generators.signals.trigger.min_separation);
  // must be >= that min_separation.
  double frame_min_separation = 0.5;
  int exposures = 1;                // each step 2 frame taken this many times, 1 .. 20
  double hall_background_s = 12.0;  // background Hall recording (MCU time), (0, 3600]
  double hall_actual_min_s = 15.0;  // the actual recording runs through step 2; at least this
  // How far beside the world board the screen may carry the reflected spots, in squares
  // ([0, 100]): the quality gate counts a step 2 frame's dots within the board grown by this.
  double dot_margin_squares = 1.0;
};

struct RigFile {
  std::string origin;  // the file name, for messages
  std::string text;    // the file's text (journalled by a session)
  gen::RigGeneratorConfig generators;
  RigCamera camera;
  hall_mcu::HallMcuConfig hall_mcu;
  dataset::BoardSpec world_board, sliding_board;
  RigBeams beams;
  SlidingPlate sliding_plate;
  Step1Design step1;
  Step2Design step2;
};

// Reads and validates `file` (see above). Throws std::runtime_error.
RigFile LoadRigFile(const std::filesystem::path& file);
// Same from YAML text; `origin` names it in messages.
RigFile ParseRigFile(const std::string& yaml_text, const std::string& origin);

}  // namespace msmcal::rig

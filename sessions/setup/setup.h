#pragma once
// The person at the rig as data (docs/lab-path.md): every physical change a session needs is one
// `Setup` — the whole physical state wanted (absolute), what differs from the previous set-up,
// and the frames or Hall recording it is for — rendered to the console's instruction block or
// sent as JSON to a hook program (a motorised rig, the twin's `msmcal mock hands`).
//
// Set-ups are designed from a plan (PlanSetups): consecutive frames of one step with equal
// physical state (camera position, MSM and top frame mounted, sliding plate pose, unblocked
// beams) share one set-up, so repeated exposures and frames that differ only in their trigger
// selection or their drive mode do not ask again. Each Hall recording is a set-up of its own
// (its recording starts when it is confirmed). Neither the trigger selection nor the drive mode
// is physical: the generators play each frame's triggers and switch the drives per frame
// (docs/lab-path.md, "Per-frame signals"); `drive` is information only.
//
// JSON (one object, UTF-8, one line when sent to a hook):
//   {"msmcal_setup": 1, "kind": "setup", "block": 3, "of": 24,
//    "for": {"step": "step1" | "hall_background" | "hall_actual" | "step2",
//            "frames": ["step1/0003.png", ...]},
//    "camera": "C1" | "C2", "msm_mounted": false, "top_frame_mounted": true,
//    "sliding_plate": {"mounted": true, "pose": 2, "distance_mm": 35.0, "tilt_deg": 12.0}
//                     (or {"mounted": false}),
//    "beams_unblocked": [1, 2, 3], "drive": "off" | "fast_only" | "scan" (information: the
//    generators' drive mode at the set-up's first frame),
//    "changes": ["..."], "text": "<the rendered instruction block>"}
//   {"msmcal_setup": 1, "kind": "truth_request", "dir": "/abs/session/truth"}
// `block` counts from 1; `pose` is the plan's 0-based pose index (session.yaml), the texts say
// "pose <pose + 1> of <poses>".

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"

namespace msmcal::setup {

enum class SetupStep { kStep1, kHallBackground, kHallActual, kStep2 };
const char* ToString(SetupStep step);  // "step1" | "hall_background" | "hall_actual" | "step2"

enum class Drive { kOff, kFastOnly, kScan };
const char* ToString(Drive drive);  // "off" | "fast_only" | "scan"

struct SlidingPlateState {
  bool mounted = false;
  int pose = 0;            // plan pose index (0-based); only when mounted
  double distance_mm = 0;  // from the mirror's position towards the source; only when mounted
  double tilt_deg = 0;     // only when mounted
  bool operator==(const SlidingPlateState& o) const;
};

// The physical state of the rig (everything a person or a motor changes).
struct RigState {
  std::string camera = "C1";  // "C1": step-1 position (both boards); "C2": step 2 (world board)
  bool msm_mounted = false;
  bool top_frame_mounted = true;
  SlidingPlateState sliding_plate;
  std::vector<int> beams_unblocked;  // ascending
  bool operator==(const RigState& o) const;
  bool operator!=(const RigState& o) const { return !(*this == o); }
};

struct Setup {
  int block = 0;  // 1-based position among the session's set-ups
  int of = 0;     // set-ups in the session
  SetupStep step = SetupStep::kStep1;
  std::vector<std::string> frames;    // plan frames taken at this set-up (empty for Hall set-ups)
  std::vector<size_t> frame_indices;  // their indices into plan.step1 / plan.step2 (not in JSON)
  RigState state;
  // Information, not physical: the drive mode the generators play at the set-up's first frame
  // (a step 2 set-up may cover neutral, fast-only and scan frames; the Hall set-ups: scan).
  Drive drive = Drive::kOff;
  std::vector<std::string> changes;  // what differs from the previous set-up (all, for the first)
  std::string text;                  // the console's instruction block
  bool operator==(const Setup& o) const;
};

// Where the sliding plate goes at each pose (rig file's sliding_plate, or the simulator's step 1
// options); poses without an entry get no distance/tilt hint (0).
struct PoseGeometry {
  double distance_mm = 0;
  double tilt_deg = 0;
};

struct SetupPlan {
  std::vector<Setup> setups;     // in the order the orchestrator asks for them
  std::vector<int> step1_setup;  // per plan.step1 frame: index into setups
  std::vector<int> step2_setup;  // per plan.step2 frame
  int background_setup = -1, actual_setup = -1;
};

// The set-ups of `plan` in the orchestrator's order: step 1 frames, the background Hall
// recording, the actual Hall recording, step 2 frames; with background_first the background set-up
// comes first (the orchestrator asks for the MCU's device before the rig check; the recording
// follows step 1 without another prompt). Texts rendered (RenderSetupText).
SetupPlan PlanSetups(const dataset::Recording& plan, const std::vector<PoseGeometry>& poses,
                     bool background_first = false);

// The console's instruction block for `s` (header "=== [block/of] title ===" and numbered
// items), from the Setup's fields and the plan (trigger times, beam list, frame counts).
std::string RenderSetupText(const Setup& s, const dataset::Recording& plan, bool background_first);

std::string SetupToJson(const Setup& s);  // one line
// Parses SetupToJson's form (frame_indices are not carried: empty). Throws std::runtime_error
// naming the field for anything else.
Setup SetupFromJson(const std::string& json);
std::string TruthRequestJson(const std::filesystem::path& dir);  // dir made absolute

}  // namespace msmcal::setup

#pragma once
// `msmcal plan`: the session plan designed from a rig file (docs/lab-path.md). The plan is the
// interchange format's session.yaml + camera.yaml without images: boards, beams, the drive, the
// clock, the trigger table (processing/signal's sparse design from the rig's drive and trigger
// settings) and the frames to take (processing/plan: step 1 per pose with background,
// identification and repeated exposures; step 2 neutral, fast-only and scan frames, triggers
// grouped so that no two of a frame are closer than step2.frame_min_separation in signal space).

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "sessions/rig/rig_file.h"
#include "sessions/setup/setup.h"

namespace msmcal::plan {

// Designs the plan. Throws std::invalid_argument naming the field, the value and the limit when
// the rig's limits forbid it (the rig file was validated by LoadRigFile; this re-checks what a
// plan adds: at least 3 triggers, frames within the interchange format's references).
dataset::Recording DesignSessionPlan(const rig::RigFile& rig);

// Where the sliding plate goes at each pose (for the set-ups' hints and the hook JSON).
std::vector<setup::PoseGeometry> PoseGeometryOf(const rig::RigFile& rig);

// What a plan costs, as `msmcal plan` and `session run --dry-run` print it.
struct PlanSummary {
  size_t step1_frames = 0, step2_frames = 0, triggers = 0;
  int setups = 0;  // instruction blocks: prompts a person sees (console) or hook calls
  double expected_duration_s = 0;
  uint64_t disk_bytes = 0;  // upper estimate of the session folder
  std::string text;         // the printed summary (several lines)
};
// Duration model (documented in docs/lab-path.md): kSecondsPerChange per set-up, two frame
// periods plus the settle time per frame (one stale, one fresh), the Hall background recording,
// the step 2 duration at least step2.hall_actual_min_s. Disk: each frame as 8-bit raw bytes
// twice (session folder + journal), the Hall CSVs at about 40 bytes per reading twice.
inline constexpr double kSecondsPerChange = 30.0;
PlanSummary SummarisePlan(const dataset::Recording& plan, const rig::RigFile& rig);

// The plan against the rig (for `session run --rig ... --plan ... --dry-run`): the drive of the
// plan equals the rig's (the limits checked the rig's), the camera size, boards, beam count, the
// trigger table within the rig's trigger limits (duty, max_triggers, inside the pattern period).
// Empty when it fits; otherwise the first problem naming field, value and limit.
std::string CheckPlanAgainstRig(const dataset::Recording& plan, const rig::RigFile& rig);

// Writes session.yaml and camera.yaml into `dir` (created), reads them back with the interchange
// reader. Throws what the reader throws.
void WritePlanFolder(const std::filesystem::path& dir, const dataset::Recording& plan);

}  // namespace msmcal::plan

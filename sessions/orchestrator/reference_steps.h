#pragma once
// A session that starts at step 2 (a rig sweep's point, docs/lab-path.md "Rig sweeps"): step 1
// and the background Hall recording are another session's (the reference), reused as they are;
// the rig check, the actual Hall recording and step 2 are taken anew by RunSession. The result
// is a complete interchange folder of its own: the reference's step 1 images and
// hall/background.csv are hard-linked (copied across file systems) into it and journalled as
// recorded.

#include <filesystem>
#include <memory>
#include <string>

#include "processing/dataset/recording.h"
#include "sessions/orchestrator/orchestrator.h"

namespace msmcal::store {
class SessionStore;
}

namespace msmcal::orchestrator {

// Creates the journal of a new session in `dir` (absent or empty; else std::runtime_error) as
// RunSession starts one: the journal metadata of `options`, the plan (what RunSession with
// `resume` compares its plan with), the trigger table, every step pending. RunSession calls it;
// SeedSessionFromReference builds a session that starts at step 2 on it.
std::unique_ptr<store::SessionStore> CreateSessionJournal(const OrchestratorOptions& options,
                                                          const dataset::Recording& plan,
                                                          const std::filesystem::path& dir,
                                                          const store::Clock& clock);

// The plan of a session that reuses `reference`'s step 1 (a session folder as ReadRecording
// reads it; `reference_name` names it in messages): its camera (camera.yaml, the calibrated
// intrinsics), boards, beams and step 1 frames (those its session.yaml lists, i.e. the accepted
// ones), with `designed`'s drive, clock, trigger table and step 2 frames (plan::DesignSessionPlan
// of the point's rig file). Throws std::runtime_error naming the reference and the field when
// the boards, the beam list or the camera's sensor size differ from `designed`'s (the step 1
// frames would not be of this rig), or when the reference has no step 1 frame.
dataset::Recording PlanWithReferenceStep1(const dataset::Recording& reference,
                                          const std::string& reference_name,
                                          const dataset::Recording& designed);

// Creates options.out_dir (absent or empty, else std::runtime_error) as a session whose step 1
// and background Hall recording are `reference_dir`'s: the journal as RunSession creates it
// (CreateSessionJournal with `plan`, normally PlanWithReferenceStep1's), the reference's step 1
// images of `plan` and hall/background.csv (with its clock file) linked in and journalled as
// recorded (frames accepted, readings and clock edges stored), the steps step1 and
// hall_background done, the rig check, step 2 and session_written pending. RunSession with
// options.resume = true then checks the rig, takes the actual Hall recording with step 2 and
// writes session.yaml. Built in a staging folder beside out_dir (".<name>.seeding") and renamed
// into place, so that a kill leaves either no session or a complete seed (a stale staging
// folder is removed by the next call). Throws std::runtime_error naming the missing file.
void SeedSessionFromReference(const OrchestratorOptions& options, const dataset::Recording& plan,
                              const std::filesystem::path& reference_dir);

}  // namespace msmcal::orchestrator

#pragma once
// Frame lists of a session plan, pure: which step 1 frames to take at which sliding-plate pose
// with which beams, and how trigger indices are grouped into step 2 frames so that no two dots
// of one frame come closer than a separation rule. Used by `msmcal plan` (sessions/plan, from a
// rig file) and by the rig simulator (mocks/rig, which adds its geometric checks).

#include <cstddef>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"

namespace msmcal::plan {

// "step1/0003.png": the file name of the i-th frame of a step.
std::string FrameFile(const char* step, size_t index);

struct Step1FrameOptions {
  int poses = 7;
  int beams = 3;  // ids 1..beams
  bool identification_frames = true;
  bool background_frames = true;
  int exposures = 1;  // each frame this many times in a row
  // Per pose (may be empty: none): the pose's dots lie too close together for one all-beams
  // frame; it gets one frame per beam instead (and keeps its background frame).
  std::vector<bool> close_pose;
};

// Per pose: a frame with every beam (or, at a close pose, one frame per beam) and a background
// frame with every beam blocked; identification frames (one per beam alone) at the last pose,
// which then needs no all-beams nor background frame unless it is close. Then every frame
// `exposures` times in a row, renumbered. Throws std::invalid_argument for poses < 1, beams < 1,
// exposures < 1.
std::vector<dataset::Step1Frame> DesignStep1Frames(const Step1FrameOptions& options);

// A trigger's predicted dot position in signal space (each drive normalised to [-1, 1]).
struct SignalPoint {
  double fast = 0;
  double slow = 0;
};
double Distance(const SignalPoint& a, const SignalPoint& b);

// Groups the indices 0..points.size()-1 into frames: every index in exactly one group, at most
// max_per_group per group, no two indices of a group closer than min_separation. First fit in
// index order (a group takes index i when it has room and i keeps the rule with every member).
// Each group is sorted. Throws std::invalid_argument for max_per_group < 1.
std::vector<std::vector<int>> GroupBySeparation(const std::vector<SignalPoint>& points,
                                                int max_per_group, double min_separation);

// `frames` groups of up to per_frame indices for the fast-only frames (only the fast drive on:
// points are compared on their fast coordinate alone): frame f starts its greedy pass at index
// f * n / frames (so the frames sample different parts of the fast motion), and takes an index
// that keeps min_separation from the frame's others. Groups are sorted; an empty group is left
// out.
std::vector<std::vector<int>> ChooseFastOnlyGroups(const std::vector<SignalPoint>& points,
                                                   int frames, int per_frame,
                                                   double min_separation);

}  // namespace msmcal::plan

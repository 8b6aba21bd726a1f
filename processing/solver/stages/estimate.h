#pragma once
// Stage: the maximum-likelihood estimate (MSM paper Sec. V-A4, eqs. 4-8). Repeated views of a
// static board are merged into one view each (docs/solver.md, "Covariance honesty"), initial
// values come in closed form (initialise.h), and the MLE refines everything and gives the
// per-plane covariances (mle.h).

#include <string>
#include <vector>

#include "processing/solver/mle.h"
#include "processing/solver/model.h"
#include "processing/solver/stages/common.h"

namespace msmcal::solver {

// Frames of a static board seen by a fixed camera (the world board in every step 1 frame for
// C1 and in every step 2 frame for C2, a sliding pose seen in several frames) repeat the same
// view: their corner errors are mostly the detector's per-corner bias, the same in every frame,
// not independent noise. Each view enters the MLE once, as the mean of its frames' corners, so
// that the pose information is not counted K times (docs/solver.md, "Covariance honesty").
// A corner is averaged over the frames where it is clear of laser dots (`clear[k][i]`); a
// corner that no frame sees clear is left out of the view, and a view left with fewer than 4
// corners is left out whole. `dropped` counts the corners left out.
std::vector<CornerSet> MergeRepeatedViews(const std::vector<CornerSet>& sets,
                                          const std::vector<std::vector<char>>& clear,
                                          int* dropped);

// Corners of a repeated view (as MergeRepeatedViews groups them) that one frame puts off where
// the view's other frames agree they are: a plate moved in front of part of a board cuts the
// squares around the corners next to its edge, and the detector still returns those corners,
// biased (0.1-1 px on scripts/random_scenes.py seed 118, where the sliding plate overlapped the
// world board's last column of squares in 8 of 24 step 1 frames). Per view of at least
// `min_frames` frames: each corner's median position over the frames where it is clear (after
// each frame's median shift, so that a camera that moved a little is not taken for occlusion);
// a frame's corner farther than max(k_sigma * s, min_threshold_px) from it, s the view's robust
// per-axis scatter (the median distance / 1.1774, Rayleigh), is marked not clear in `clear`.
// Corners clear in fewer than `min_frames` frames are left as they are.
struct CornerConsistencyOptions {
  int min_frames = 3;
  double k_sigma = 5.0;
  double min_threshold_px = 0.05;
};
struct CornerConsistency {
  int marked = 0;               // corner observations marked not clear
  int frames_affected = 0;      // of the sets given
  double max_threshold_px = 0;  // the largest threshold a view used
};
CornerConsistency MarkInconsistentCorners(const std::vector<CornerSet>& sets,
                                          std::vector<std::vector<char>>* clear,
                                          const CornerConsistencyOptions& options = {});

struct MleEstimate {
  Observations obs;  // as given, with repeated views merged
  MleResult mle;
  StageLog log;  // fails when no initial values can be formed or the MLE is not usable
};
// `corners_clear[k]` belongs to obs.corners[k] (CornersClearOfDots).
MleEstimate EstimateMle(Observations obs, const std::vector<std::vector<char>>& corners_clear,
                        const MleOptions& options);

}  // namespace msmcal::solver

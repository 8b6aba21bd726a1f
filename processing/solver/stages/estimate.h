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

struct MleEstimate {
  Observations obs;  // as given, with repeated views merged
  MleResult mle;
  StageLog log;  // fails when no initial values can be formed or the MLE is not usable
};
// `corners_clear[k]` belongs to obs.corners[k] (CornersClearOfDots).
MleEstimate EstimateMle(Observations obs, const std::vector<std::vector<char>>& corners_clear,
                        const MleOptions& options);

}  // namespace msmcal::solver

#pragma once
// Stage: trigger assignment (docs/solver.md, "Trigger assignment"). A frame exposed over several
// triggers shows one mirror plane per trigger but does not say which is which: the planes'
// poses in a provisional home frame are fitted to a drive-phase model of the trigger times
// (RANSAC, then refinement with harmonics) and each frame's groups get the permutation of its
// triggers that fits best. Then the groups become mirror planes, one per (kind, trigger index).

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/solver/model.h"
#include "processing/solver/solve_types.h"
#include "processing/solver/stages/common.h"
#include "processing/solver/stages/step2_groups.h"

namespace msmcal::solver {

// Trigger-index assignment, exposed for tests. Each group is one mirror plane from a frame with
// several triggers; its pose angles (deg) are in a provisional home frame. For each frame, finds
// the permutation of its trigger indices that best fits the model
//   angle_k(t) = c_k + sum over axes a, harmonics h of (s sin(h w_a t) + c cos(h w_a t)),
// with the slow axis off in fast_only frames. Returns, per group, the assigned index into its
// frame's trigger list, or -1 for a group the model does not predict within
// options.ransac_inlier_deg at any of its frame's free slots (a wrong pairing of dots: the
// model is refined on the inliers only, so one such plane cannot pull the others off).
// `groups_of_frame[f]` lists the group indices of frame f.
struct TriggerGroup {
  int frame = 0;
  Eigen::Vector2d angles_deg = Eigen::Vector2d::Zero();
};
struct TriggerFrame {
  std::vector<double> t_s;  // trigger times of the frame
  bool slow_on = true;      // false for fast_only
};
// The fitted drive-phase model: predicted angles (deg) at trigger time t.
struct TriggerModel {
  Eigen::MatrixXd coef;  // features x 2; empty when no multi-trigger frame was assigned
  bool harmonics = false;
  double fast_hz = 0, slow_hz = 0;
  Eigen::Vector2d Predict(double t_s, bool slow_on) const;
};
std::vector<int> AssignTriggers(const std::vector<TriggerFrame>& frames,
                                const std::vector<TriggerGroup>& groups,
                                const std::vector<Eigen::Vector2d>& neutral_angles_deg,
                                double fast_hz, double slow_hz, const PipelineOptions& options,
                                std::string* note, TriggerModel* model = nullptr);

// The stage: `groups` with their trigger slots set, then the `recovered` groups that the
// fitted model confirms (in a free slot of their frame). Fails when there is no group or a
// frame lists a trigger that session.yaml does not define.
struct TriggerAssignment {
  std::vector<Group> groups;
  // Per step 2 view: planes left out because the drive-phase model does not predict them at any
  // of the frame's free triggers (a wrong pairing of dots); the frame is then partly used.
  std::vector<int> off_model;
  StageLog log;
};
TriggerAssignment AssignTriggerSlots(const std::vector<Step2View>& views, std::vector<Group> groups,
                                     std::vector<Group> recovered,
                                     const std::vector<dataset::Trigger>& triggers,
                                     const dataset::Drive& drive, const PipelineOptions& options);

// The mirror planes: one per (kind, j) (j = -1 for neutral; neutral frames share one plane).
struct MirrorPlanes {
  std::vector<std::pair<dataset::Step2Kind, int>> keys;  // per plane index
  std::vector<ReflectedDot> estimate_dots;               // the estimate beams' dots, for the MLE
  std::vector<ReflectedDot> validation_dots;             // the held-out beams' dots
  int num_neutral = 0, num_fast_only = 0, num_scan = 0;
  StageLog log;  // fails without a neutral plane, without a fast-only plane, or with one that
                 // is within kMinSingleFastOnlyTiltDeg of the neutral
};
// With a single fast-only plane {0}'s fast axis comes from it and the neutral plane
// (geometry::FastAxisWithNeutral); closer than this they do not determine it.
inline constexpr double kMinSingleFastOnlyTiltDeg = 0.5;
MirrorPlanes CollectMirrorPlanes(const std::vector<Step2View>& views,
                                 const std::vector<Group>& groups, const BeamTable& beams);

}  // namespace msmcal::solver

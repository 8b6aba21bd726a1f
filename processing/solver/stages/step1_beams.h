#pragma once
// Stage: step 1, the incident beams (MSM paper Sec. V-A1). In every step 1 frame the sliding
// board gives the plate's pose (PnP) and its laser dots are back-projected onto it, in {W}
// through the world board seen by the same camera C1. Dots are labelled with their beams
// (identification frames first, then each frame by the best permutation against the beams'
// predictions), the labels are checked against a line fit, and each beam is fitted (eq. 2).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/geometry/plane_line.h"
#include "processing/geometry/rigid3.h"
#include "processing/solver/model.h"
#include "processing/solver/solve_types.h"
#include "processing/solver/stages/common.h"
#include "processing/solver/stages/measure.h"

namespace msmcal::solver {

// A step 1 dot farther than this from its beam's line (fitted to all its labelled dots) marks
// its frame's dot-to-beam labels as wrong (a non-laser blob counted as a dot, or a swapped
// permutation); the frame is dropped from the beam fit (docs/solver.md, "Step 1 label check").
// Correctly labelled sliding-board dots sit ~0.05 mm from the line in simulation.
constexpr double kMaxBeamLineResidualMm = 1.0;
// A step 1 frame with more blobs on the plate than beams keeps this many surplus candidates
// (the roundest) for the beams' lines to choose from.
constexpr size_t kSurplusStep1Candidates = 4;

// A step 1 frame whose sliding board and laser dots (one per listed beam) were found.
struct Step1View {
  std::string file;
  int pose = 0;                   // sliding pose, numbered in order of first use
  std::vector<int> beams;         // beam indices (BeamTable) listed for the frame
  std::vector<vision::Dot> dots;  // candidate laser dots, unlabelled (may be more or fewer than
                                  // beams: LabelBeams labels those that lie on a beam)
  geometry::Rigid3d c1_from_sliding;
  std::vector<Eigen::Vector3d> dots_in_world;  // per dot, through world_from_pose
};

// Boards and dots of the step 1 frames.
struct Step1Frames {
  std::vector<Step1View> views;
  // Board views for the MLE (C1 world and sliding), and per view which corners no dot touches.
  std::vector<CornerSet> corners;
  std::vector<std::vector<char>> corners_clear;
  int num_poses = 0;
  std::optional<geometry::Rigid3d> c1_from_world;       // from the frame with most world corners
  std::vector<geometry::Rigid3d> world_from_pose;       // per sliding pose
  Eigen::Vector3d sliding_z = Eigen::Vector3d::Zero();  // sum of the plates' Z axes in {W}
  std::vector<FrameDetection> detections;               // the input rows, step 1 rows completed
  StageLog log;
};
// `images[i]` and `detections[i]` belong to recording.step1[i] (the rows beyond are passed
// through). Fails when a frame lists an unknown beam or no frame shows the world board.
Step1Frames MeasureStep1Frames(const dataset::Recording& recording,
                               const std::vector<ImageMeasurement>& images,
                               std::vector<FrameDetection> detections, const BeamTable& beams,
                               const PipelineOptions& options);

// Dot-to-beam labels and the initial beams.
struct BeamLabels {
  std::vector<std::vector<int>> label;   // per view, the beam index of each dot (-1: unlabelled)
  std::vector<geometry::Line> beams;     // per beam, fitted to its labelled dots (eq. 2)
  std::vector<SlidingDot> sliding_dots;  // the labelled dots, for the MLE
  StageLog log;  // frames whose labels could not be made or failed the line check
};
// Fails when a beam ends up with dots on fewer than two sliding poses.
BeamLabels LabelBeams(const std::vector<Step1View>& views,
                      const std::vector<geometry::Rigid3d>& world_from_pose,
                      const Eigen::Vector3d& sliding_z, const BeamTable& beams);

}  // namespace msmcal::solver

#pragma once
// Stage: step 2, the reflected dots and their mirror planes (MSM paper Sec. V-A2). In every
// step 2 frame the world board gives C2's pose and the laser dots on the world plane are
// back-projected into {W}. The dots of one frame are then grouped into mirror planes, one per
// trigger: each tuple of estimate-beam dots defines a plane (eq. 3) that predicts every beam's
// reflected dot, and the most consistent disjoint groups are kept.

#include <Eigen/Core>
#include <map>
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

// A step 2 frame whose world board was found and whose dot count can be grouped.
struct Step2View {
  dataset::Step2Frame frame;  // as in session.yaml
  int index = 0;              // in recording.step2
  std::vector<vision::Dot> dots;
  std::vector<Eigen::Vector3d> dots_in_world;  // through c2_from_world (zero if it misses)
  std::vector<bool> near_edge;  // the dot's spot reaches a square edge of the world board
  bool partial = false;         // fewer dots than triggers x beams
};

struct Step2Frames {
  std::vector<Step2View> views;
  std::vector<CornerSet> corners;  // C2 world-board views for the MLE
  std::vector<std::vector<char>> corners_clear;
  std::optional<geometry::Rigid3d> c2_from_world;  // from the first usable frame
  std::vector<FrameDetection> detections;          // the input rows, step 2 rows completed
  StageLog log;
};
// `images[s1 + i]` and `detections[s1 + i]` belong to recording.step2[i], s1 =
// recording.step1.size(). Fails when no step 2 frame is usable.
Step2Frames MeasureStep2Frames(const dataset::Recording& recording,
                               const std::vector<ImageMeasurement>& images,
                               std::vector<FrameDetection> detections,
                               const PipelineOptions& options);

// One mirror plane: the dots of one trigger of one frame.
struct Group {
  int frame = 0;                   // index into the step 2 views
  std::map<int, int> dot_of_beam;  // beam index -> dot index in the frame
  geometry::Plane plane;
  int slot = 0;  // index into the frame's trigger list (set by the trigger assignment)
};

struct ReflectionGroups {
  std::vector<Group> groups;
  // Built by elimination from the estimate beams' dots alone (the frame's other triggers
  // complete, its held-out dots missing); kept only if the drive-phase model agrees.
  std::vector<Group> recovered;
  // Per view: how a frame with missing dots was used in part (empty: not partial).
  std::vector<std::string> partial_note;
  StageLog log;
};
ReflectionGroups GroupReflections(const std::vector<Step2View>& views,
                                  const std::vector<geometry::Line>& beams,
                                  const BeamTable& beam_table, const geometry::CameraModel& camera,
                                  const geometry::Rigid3d& c2_from_world,
                                  const PipelineOptions& options);

}  // namespace msmcal::solver

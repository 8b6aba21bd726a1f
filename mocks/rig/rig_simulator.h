#pragma once
// The rig simulator: a physical model of the calibration rig with ground truth, deterministic
// for a given SimOptions (seed included).
//
// Geometry (all in {W}, the world board frame: origin at the board's origin inner corner, Z
// into the board, so the printed side faces -Z):
// - Mirror rotation centre X_O at (board_aim, -mirror_distance). The nominal neutral mirror
//   reflects the central incident beam (travelling roughly along +X_W, i.e. parallel to the
//   board) straight onto the board at board_aim; the mount is then tilted by mount_tilt_deg.
//   {0} is built with geometry::MirrorHomeFrame (fast axis X0 in the X_W-Z_W plane, slow axis
//   ~Y_W), so truth follows the interchange conventions by construction.
// - Beams: a fan about the central direction (fan plane spanned by it and Y_W), each crossing
//   the neutral mirror plane at its offset from X_O (they miss the rotation centre). The fan
//   angle is solved so that the outer beams' light-path plane normals span
//   beams.spanning_angle_deg at the neutral pose (the paper's theta).
// - Step 1 (MSM not mounted): the sliding board is centred on the central incident line at
//   distances nearest..farthest from X_O towards the source, facing the source; camera C1 sees
//   it and the world board. Step 2: camera C2 sees the world board.
// Mirror motion: MirrorMotion; mirror plane in {W} = WorldPlaneFromPose(world_from_mirror0,
// pose(t)).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "mocks/render/renderer.h"
#include "mocks/rig/hall_model.h"
#include "mocks/rig/mirror_motion.h"
#include "mocks/rig/sim_options.h"
#include "processing/dataset/recording.h"
#include "processing/geometry/camera_model.h"
#include "processing/geometry/mirror_frame.h"
#include "processing/geometry/plane_line.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::sim {

// A laser dot's identity and its true (noise-free) projection.
struct DotTruth {
  int beam = 0;  // beam id (1-based)
  int j = -1;    // trigger index; -1 for step 1 and neutral frames
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // camera.Project (with distortion)
};

// Everything a camera sees in one frame: the renderer's input plus the dots' identities
// (dots[i] and labels[i] describe the same spot).
struct Scene {
  geometry::CameraModel camera;
  std::vector<render::SceneBoard> boards;
  std::vector<render::SceneDot> dots;
  std::vector<DotTruth> labels;
};

// Solves the simple trigger table: `candidates` evenly spaced pattern times visited in a
// scrambled but fixed order; a time is accepted if every beam's scan dot lands on the board
// (margin) and in the image, at least min_separation_px from every dot of the accepted times.
// Returns ascending times (j = index). Replaceable by processing/signal's paper rule.
class RigSimulator;
std::vector<double> SimpleTriggerTimes(const RigSimulator& sim);

// The physical set-up of the rig at one instant, for scenes that follow from the rig's state
// rather than from the simulator's own plan (the digital twin, simulation/twin/physical_twin.h).
struct RigState {
  int camera = 2;           // 1: the camera at C1, 2: at C2
  bool msm_mounted = true;  // false: the beams travel on past the mirror's place
  std::optional<geometry::Rigid3d> world_from_sliding;  // the sliding plate, when mounted
  std::vector<int> unblocked_beams;                     // beam ids (1-based) that reach the rig
};

// One laser pulse that fired during an exposure: its trigger index (-1: none) and the mirror's
// pose at its time (ignored when the MSM is not mounted).
struct PulseAtPose {
  int j = -1;
  geometry::MirrorPose pose;
};

class RigSimulator {
 public:
  // Builds the rig. Throws std::invalid_argument with Validate()'s message, or
  // std::runtime_error when the geometry cannot be built (e.g. unreachable spanning angle).
  explicit RigSimulator(const SimOptions& options);
  // The same rig with a given trigger table (ascending generator times within one pattern period,
  // e.g. the pulses a generator actually fires) instead of SimpleTriggerTimes; step 2 frames are
  // built over it. Throws as above, or std::invalid_argument for an empty table.
  RigSimulator(const SimOptions& options, const std::vector<double>& trigger_times_s);

  const SimOptions& options() const { return options_; }
  const geometry::CameraModel& camera() const { return camera_; }
  const MirrorMotion& motion() const { return motion_; }
  const HallModel& hall() const { return hall_; }
  double pattern_period_s() const { return period_s_; }

  // Ground-truth geometry.
  const geometry::Rigid3d& world_from_mirror0() const { return world_from_mirror0_; }
  const std::vector<geometry::Line>& beams_in_world() const { return beams_; }  // [id - 1]
  const std::vector<Eigen::Vector3d>& beam_sources_in_world() const { return sources_; }
  const geometry::Rigid3d& c1_from_world() const { return c1_from_world_; }
  const geometry::Rigid3d& c2_from_world() const { return c2_from_world_; }
  const std::vector<geometry::Rigid3d>& world_from_sliding() const { return world_from_sliding_; }
  geometry::Rigid3d c1_from_sliding(int pose) const;
  double fan_angle_deg() const { return fan_angle_deg_; }
  // Spanning angle (deg) between the outermost beams' light-path plane normals for a mirror plane.
  double SpanningAngleDeg(const geometry::Plane& mirror_in_world) const;
  static geometry::Plane WorldBoardPlane() {
    return geometry::Plane{Eigen::Vector3d::UnitZ(), 0.0};
  }

  // Mirror plane in {W} at generator time t_s.
  geometry::Plane MirrorPlaneInWorld(double t_s, DriveMode mode) const;
  // The reflected dot of beam `beam_id` on the world plane, or empty if the reflected ray does
  // not reach it.
  std::optional<Eigen::Vector3d> ReflectedDotInWorld(int beam_id,
                                                     const geometry::Plane& mirror) const;
  // The dot of beam `beam_id` on sliding pose `pose` (step 1, no mirror).
  std::optional<Eigen::Vector3d> SlidingDotInWorld(int beam_id, int pose) const;

  // Scenes. Beam ids 1..count; trigger indices into triggers().
  Scene Step1Scene(int pose, const std::vector<int>& beam_ids) const;
  Scene Step2Scene(DriveMode mode, const std::vector<int>& trigger_indices,
                   const std::vector<int>& beam_ids) const;
  Scene FrameScene(const dataset::Step1Frame& frame) const;
  Scene FrameScene(const dataset::Step2Frame& frame) const;
  // Render from state: what the camera of `state` sees when `pulses` fire during its exposure.
  // Each pulse sends every unblocked beam from its source: it lands on the sliding plate when
  // the plate is in its way (before the mirror, or after it), else it is reflected by the mirror
  // at the pulse's pose (MSM mounted) and lands on the plate or the world board. Dots that fall
  // on the same spot (the same pose repeating over several pattern periods) are one dot.
  // Labels carry the pulse's j when the MSM reflected the beam, -1 otherwise.
  Scene StateScene(const RigState& state, const std::vector<PulseAtPose>& pulses) const;
  // world_from_sliding of step 1 pose `pose` (0-based, any index: the design's spacing
  // continues), optionally placed at distance_mm from X_O along the central incident beam and
  // tilted by tilt_deg (signed, as sessions/rig's SlidingPlate::TiltDeg gives it; by default the
  // design's tilt with its sign alternating per pose).
  geometry::Rigid3d SlidingPose(int pose, std::optional<double> distance_mm = std::nullopt,
                                std::optional<double> tilt_deg = std::nullopt) const;

  // The trigger table and the frame lists (computed at construction).
  const std::vector<dataset::Trigger>& triggers() const { return triggers_; }
  const std::vector<dataset::Step1Frame>& step1_frames() const { return step1_; }
  const std::vector<dataset::Step2Frame>& step2_frames() const { return step2_; }

  // The session (everything but images, truth and results). with_hall: also record both Hall
  // recordings with HallSampler (seeded by options().seed).
  dataset::Recording MakeRecording(bool with_hall) const;

  // The renderer's options for a frame (seed derived from options().seed and the frame index).
  render::RenderOptions RenderOptionsFor(uint64_t frame_index) const;
  // Renders a scene with RenderOptionsFor(frame_index) (e.g. the mock camera's frame counter).
  cv::Mat RenderScene(const Scene& scene, uint64_t frame_index) const;
  // The image of step1_frames()[i] / step2_frames()[i] (deterministic: seed and index).
  cv::Mat RenderStep1Frame(size_t i) const;
  cv::Mat RenderStep2Frame(size_t i) const;

  // Problems found while building (dots off the board or the image, boards overlapping in
  // C1): human-readable, one per problem. Empty for a sound configuration.
  const std::vector<std::string>& warnings() const { return warnings_; }

  // True if `p_in_world` is on the world board's inner-corner area shrunk by margin_mm, and
  // projects into C2's image at least margin_px from the border.
  bool OnWorldBoardInC2(const Eigen::Vector3d& p_in_world, double margin_mm,
                        double margin_px) const;

 private:
  void Build(const std::vector<double>* trigger_times_s);
  void BuildGeometry();
  void BuildFrames(const std::vector<double>* trigger_times_s);
  bool InImage(const Eigen::Vector2d& px, double margin_px) const;

  SimOptions options_;
  MirrorMotion motion_;
  HallModel hall_;
  double period_s_ = 0;
  geometry::CameraModel camera_;
  geometry::Rigid3d world_from_mirror0_;
  std::vector<geometry::Line> beams_;
  std::vector<Eigen::Vector3d> sources_;
  double fan_angle_deg_ = 0;
  geometry::Rigid3d c1_from_world_;
  geometry::Rigid3d c2_from_world_;
  std::vector<geometry::Rigid3d> world_from_sliding_;
  Eigen::Vector3d central_incident_ = Eigen::Vector3d::UnitX();  // v_c
  std::vector<dataset::Trigger> triggers_;
  std::vector<dataset::Step1Frame> step1_;
  std::vector<dataset::Step2Frame> step2_;
  std::vector<std::string> warnings_;
};

}  // namespace msmcal::sim

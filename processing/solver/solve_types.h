#pragma once
// The solver's shared value types: its options, the errors and dropped frames it reports, the
// per-frame detection rows and the whole result (pipeline.h runs the stages that fill them).

#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/solver/initialise.h"
#include "processing/solver/mle.h"
#include "processing/vision/checkerboard.h"
#include "processing/vision/dots.h"

namespace msmcal::solver {

struct SolveOutput;

// A solve that cannot go on. `partial` (when set) holds what was measured and decided up to the
// failure: detections per frame, dropped frames, notes (results/detections.csv is written from
// it, so that a failed solve still says why).
class SolveError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
  SolveError(const std::string& what, std::shared_ptr<const SolveOutput> partial)
      : std::runtime_error(what), partial(std::move(partial)) {}
  std::shared_ptr<const SolveOutput> partial;
};

// Loads an image by its file name as written in session.yaml ("step1/0000.png"). Returns an empty
// Mat if it cannot be read. Called from several threads at once (PipelineOptions::image_threads).
using ImageLoader = std::function<cv::Mat(const std::string& file)>;

struct PipelineOptions {
  vision::DotOptions dots;
  vision::CheckerboardOptions boards;
  MleOptions mle;
  // Grouping of reflected dots into one mirror plane: worst accepted mean pixel inconsistency.
  double max_group_residual_px = 15.0;
  // The same for a frame with fewer dots than triggers x beams: the triggers whose dots (every
  // listed beam's) are all there are kept, each within this tighter tolerance (correct groups
  // score ~0.2 px on the simulator; with two estimate beams a wrong pairing can still fit a
  // plane, the held-out beams' dots are the check).
  double partial_frame_group_residual_px = 2.0;
  // Where a frame's laser dots are looked for: blobs inside the board's squares area grown by
  // this many squares (step 1: the sliding plate around its pattern, never on the world board;
  // step 2: the world plane, a screen around the world board).
  double step1_dot_margin_squares = 3.0;
  double step2_dot_margin_squares = 8.0;
  // Where a plate or screen is larger than those margins assume (the spots land beside the
  // pattern), the data say so: a step whose frames show their listed dots more often on the
  // board's whole plane than within the margin takes the whole plane (minus the other board)
  // for every frame of that step, with a note. Decided once per step after the first pass.
  bool dot_margin_from_data = true;
  // A laser spot is round in the plane it lands on, or elongated by its incidence (2 at 60 deg):
  // the blob's shape mapped into the board's plane through the board's homography may be at
  // most this elongated (the image-space limit is dots.max_elongation, loose: an oblique plate
  // elongates a round spot in the image).
  double max_surface_elongation = 2.0;
  // Blobs more elongated in the image than junction_elongation and within
  // junction_exclusion_squares of a detected inner corner are the top-hat's residue of the
  // checkerboard's X-junctions, not spots.
  double junction_elongation = 1.3;
  double junction_exclusion_squares = 0.25;
  // A step 2 frame with more blobs than expected is still grouped (the mirror-plane consistency
  // picks the dots) unless the surplus exceeds this.
  int max_surplus_dots = 12;
  // A frame whose dots (with `dots`) fall short of what session.yaml says it shows is measured
  // again with settings derived from the image itself (vision::AdaptiveDotOptions: threshold
  // from its noise, top-hat kernel from its board's squares); kept where it finds more.
  bool adaptive_dots = true;
  // In that pass, blobs whose peak is below this fraction of the frame's brightest blob on the
  // board's plane (or of their headroom over the background, if smaller) are refused (noise,
  // compression artefacts and board residue passed by the low threshold; one frame's laser spots
  // are alike).
  double adaptive_min_relative_peak = 0.25;
  // A frame still short of dots after that (step 1: with more or fewer than its beams) is
  // measured a third time on its difference from the static scene without it: per pixel, the
  // smallest value over the other images of its group (step 1: the same sliding pose; step 2:
  // every frame). The boards cancel there, so spots on square edges and corners, on tinted
  // squares and in blur are blobs on a flat floor, and board residue is gone. Kept where it
  // comes closer to the expected count on the board's plane.
  bool background_dots = true;
  // Blobs at the same place (within this radius, px) in images of one static group whose light
  // has nothing in common (step 1: beams; step 2: beam and trigger) are the scene's structure,
  // not spots (board-square and plate-corner residue of the top-hat), and are dropped before
  // the third pass. 0: off.
  double static_blob_radius_px = 1.0;
  // Trigger-index assignment inside multi-trigger frames (RANSAC over a drive-phase model).
  int ransac_iterations = 3000;
  double ransac_inlier_deg = 0.4;
  uint64_t seed = 1;
  // Repeated exposures of one static scene (step 1 frames with the same pose and beams; step 2
  // frames with the same kind, triggers and beams) are averaged pixel by pixel and measured as
  // one image: their noise falls by sqrt(K) while the covariance stays that of one measurement
  // (measuring them apart would count the shared background frame's noise K times). Off: each
  // frame is measured on its own.
  bool average_exposures = true;
  // The first image of each camera view (step 1, step 2) is measured first; each board found
  // there is then searched in the view's other images first where it was found, by the detector
  // and at the scale that found it (vision::BoardHint; the whole chain where that fails). The
  // world board does not move within a view: the 40 randomised scenes (a third of them found
  // only by the 2x upscaled search) took 348 s instead of 1159 s. Off: every image runs the
  // whole chain.
  bool hint_boards_from_first_frame = true;
  // Images are measured (boards, dots) this many at a time, each on its own thread with
  // OpenCV's own parallel loops off for the duration of the solve (they made the results depend
  // on the CPU count and the machine's load). The results do not depend on this number.
  int image_threads = 2;
  std::string Validate() const;
};

struct DroppedFrame {
  std::string file;
  std::string reason;
};

// What the solver measured and decided for one image (results/detections.csv, the annotated
// diagnostics). One per frame of session.yaml; repeated exposures of one scene share the
// scene's measurement (`scene` names its first exposure).
struct FrameDetection {
  std::string file;
  std::string step;  // "step1" | "step2"
  std::string scene;
  bool used = false;
  bool partial = false;  // used in part (sliding board only, some triggers, world board missing)
  std::string reason;    // why it was dropped (empty when used)
  std::string note;      // how it was used in part
  struct Board {
    std::string name;  // "world" | "sliding"
    bool found = false;
    std::string method;  // vision::ToString(BoardMethod)
    double square_px = 0;
    double corner_rms_px = -1;  // PnP reprojection RMS of its corners; -1: not computed
    std::vector<Eigen::Vector2d> corners_px;
  };
  std::vector<Board> boards;
  int blobs = 0;        // blobs that passed the image-level dot checks
  int dots_found = -1;  // on the board's plane (-1: not looked for: no board)
  int dots_expected = 0;
  vision::DotRejections rejected;                          // image-level refusals by reason
  int off_plane = 0, junction = 0, surface_elongated = 0;  // plane-level refusals
  std::vector<Eigen::Vector2d> dots_px;                    // the frame's dots on the board's plane
  std::vector<Eigen::Vector2d> refused_px;                 // blobs refused at plane level
};

struct ValidationDetail {
  dataset::ValidationRow row;       // proposed model
  dataset::ValidationRow baseline;  // baseline model (same beam and j)
  double predicted_sigma_px = 0;    // eq. 10: sqrt of the mean eigenvalue of the 2x2 covariance
  double normalised_error = 0;      // sqrt(e^T C^-1 e / 2), e = observed_px - predicted_px
  // The dot on the image (px, (0, 0) at the centre of the top-left pixel): as measured, as the
  // proposed model predicts it, and the 2x2 covariance C of their difference (eq. 10: the
  // estimate's uncertainty through the prediction plus the dot's own, with its variance factor).
  Eigen::Vector2d observed_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d predicted_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov_px2 = Eigen::Matrix2d::Zero();
  // The error whitened jointly with the other held-out dots: L^-1 e over the stacked errors of
  // every dot, L L^T their joint covariance (with the cross terms of the beam, c2 and planes they
  // share), in the order of SolveOutput::validation. It is this dot's error given the dots before
  // it, in units of its conditional covariance: with honest covariances independent N(0, I2)
  // across dots, which the marginal normalised errors are not (one beam error moves every dot
  // of that beam alike).
  Eigen::Vector2d joint_whitened = Eigen::Vector2d::Zero();
};

// One fitted residual whitened by the covariance the MLE used for it (its input covariance times
// its family's covariance_scale): A (observed - predicted) with A^T A = C^-1, N(0, I2) up to the
// leverage (each component's variance is 1 - h) when the covariances are honest.
struct WhitenedResidual {
  int family = 0;  // MleFamily
  int group = 0;   // corner set (index into Observations::corners), sliding pose, mirror plane
  Eigen::Vector2d observed_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d whitened = Eigen::Vector2d::Zero();
};

// A neutral or fast-only mirror plane (the planes that define {0}; not in mirror_planes.csv).
struct SupportPlane {
  dataset::Step2Kind kind = dataset::Step2Kind::kNeutral;
  int j = -1;  // trigger index; -1 for the neutral plane
  geometry::Plane plane_in_world;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();  // as MleResult::plane_cov
};

struct SolveOutput {
  std::vector<dataset::MirrorPlaneRow> planes;  // scan planes, ascending j
  std::vector<SupportPlane> support_planes;     // neutral, then fast-only by ascending j
  std::vector<dataset::BeamRow> beams;          // every beam (estimate and validate)
  std::vector<ValidationDetail> validation;     // by (beam id, j)
  std::vector<WhitenedResidual> residuals;      // every fitted residual, by family, in fit order
  std::vector<DroppedFrame> dropped;
  std::vector<FrameDetection> detections;  // one per frame of session.yaml, in its order
  std::vector<std::string> notes;          // what the solver decided (associations, counts)
  geometry::Rigid3d world_from_mirror0;
  // Covariance of {0}'s error [rotation vector (rad, in {W}: R_true = Exp(-e) R_est, small),
  // X_O (mm, in {W})], propagated from the neutral, fast-only and scan planes.
  Eigen::Matrix<double, 6, 6> mirror0_cov = Eigen::Matrix<double, 6, 6>::Zero();
  BaselineModel baseline;
  MleResult mle;  // estimate, covariances, Ceres figures
  double mean_spanning_angle_deg = 0;
  double rms_validation_deg = 0, rms_validation_px = 0;
  double rms_baseline_deg = 0, rms_baseline_px = 0;
  double rms_normalised_validation = 0;
  int num_neutral_planes = 0, num_fast_only_planes = 0, num_scan_planes = 0;
};

}  // namespace msmcal::solver

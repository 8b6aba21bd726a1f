#pragma once
// The Hall-sensor calibration pipeline (MSM paper Sec. V-B) and its Table II protocol.
//
// 1. Time base: each recording's MCU time -> generator time from its clock edges. Of the actual
//    recording only the pattern periods with both drives running are kept (driven_periods.h: a
//    lab session's actual recording also holds its neutral and fast-only frames' stretches).
// 2. Foreground: actual and background readings folded to pattern phase, averaged into smooth
//    periodic profiles P_A, P_B; B(t) = (P_A(t) - mean P_A) - (P_B(t) - mean P_B). Subtracting
//    each recording's own mean removes a baseline shift between the two recordings (they are
//    made at different times: the Earth's and the lab's static fields move); the mean pose goes
//    into the models' constant term.
// 3. Models with dt (hall_model.h), evaluated by random 4:1 train/test splits of the poses,
//    repeated, with the Hall readings also split 4:1 and profiled separately for training and
//    testing (so a test pose is never predicted from readings the training saw).
// 4. dt: whether the recording determines it (delta_t.h), judged on a field model's cost profile
//    and splits; the chosen model's own dt is the session's only when it is a field model and
//    the recording determines it.

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/hall/delta_t.h"
#include "processing/hall/drive_phase.h"
#include "processing/hall/driven_periods.h"
#include "processing/hall/hall_model.h"
#include "processing/hall/phase_profile.h"
#include "processing/hall/time_base.h"

namespace msmcal::hall {

struct HallCalibrationInput {
  const dataset::HallRecording* actual = nullptr;
  const dataset::HallRecording* background = nullptr;
  double pattern_period_s = 0;
  double fast_frequency_hz = 0;
  double slow_frequency_hz = 0;
  std::vector<PoseSample>
      poses;  // one per trigger: t_s in the pattern, (alpha_deg, beta_deg, trans_mm)
};

struct HallCalibrationOptions {
  TimeBaseOptions time_base;
  DrivenPeriodOptions driven_periods;  // which periods of the actual recording are the scan
  PhaseProfileOptions profile;
  DeltaTIdentificationOptions delta_t;  // when dt counts as determined by the recording
  DrivePhaseOptions drive_phase;        // dt from the drives' phases (drive_phase.h)
  double delta_t_min_s = -0.01;
  double delta_t_max_s = 0.01;
  int repetitions = 50;
  double train_fraction = 0.8;
  uint64_t seed = 1;
  std::vector<HallModelKind> models = {HallModelKind::kLinear, HallModelKind::kSine,
                                       HallModelKind::kQuadratic, HallModelKind::kCubic};
  // Optional, called after each repetition (progress lines): repetitions done and the total.
  std::function<void(int done, int total)> on_repetition;
  std::string Validate() const;
};

// A foreground signal built from (subsets of) the two recordings.
struct Foreground {
  PhaseProfile actual;
  PhaseProfile background;
  Eigen::Vector3d Value(double t_s) const {
    return (actual.At(t_s) - actual.Mean()) - (background.At(t_s) - background.Mean());
  }
};

// What set the window of the splits' second pass and of the final fit (a quarter fast period
// either side of a centre).
enum class DeltaTBracket {
  kNone,              // the whole search window
  kSteadyFieldModel,  // the mean dt of the field model whose splits agree best
  kDrivePhases,       // the drives' phases: no field model steady enough, or the steady one
                      // sits in another valley than the phases determine (splits on an alias)
};
const char* ToString(DeltaTBracket bracket);  // "none" | "steady field model" | "drive phases"
// The bracket's source and centre (*centre_s; untouched for kNone): the steadiest field model
// (its split dt's mean and standard deviation; steady below a sixteenth of the fast period)
// unless the drives' phases determine dt more than a quarter fast period away from it; else the
// phases when they choose a valley; else none.
DeltaTBracket ChooseDeltaTBracket(double steady_mean_s, double steady_std_s,
                                  const DrivePhaseEstimate& phases, double fast_frequency_hz,
                                  double* centre_s);

// Table II row: statistics over the repetitions.
struct ModelStats {
  HallModelKind kind = HallModelKind::kLinear;
  Eigen::Vector3d test_rms_mean = Eigen::Vector3d::Zero();  // alpha_deg, beta_deg, trans_mm
  Eigen::Vector3d test_rms_std = Eigen::Vector3d::Zero();
  Eigen::Vector3d train_rms_mean = Eigen::Vector3d::Zero();
  double delta_t_mean_s = 0;
  double delta_t_std_s = 0;
  std::vector<double> split_delta_t_s;  // one per repetition
};

struct HallCalibrationResult {
  TimeBase actual_time_base;
  TimeBase background_time_base;
  DrivenPeriods actual_periods;  // the actual recording's periods used (both drives running)
  // One per options.models that could be fitted, in that order. A model with more parameters
  // than the poses of a training split can determine is left out and named in skipped_models
  // ("cubic: needs more than 20 poses, 11 per training split"); when no model is left,
  // CalibrateHall throws.
  std::vector<ModelStats> table;
  std::vector<std::string> skipped_models;
  // How the table was evaluated: options.repetitions random splits of options.train_fraction,
  // or, with fewer poses than such a split needs (min_poses_for_splits), leave-one-out: one
  // repetition per pose, each held out once (repetitions = the number of poses).
  bool leave_one_out = false;
  int repetitions = 0;
  int min_poses_for_splits = 0;
  // The model with the lowest held-out chi-square (OutputScale in the .cc).
  HallModelKind best = HallModelKind::kLinear;
  HallFitResult final_fit;  // best model refitted on every pose and reading
  Foreground foreground;    // from every reading
  // The session's dt: a field model's, judged by IdentifyDeltaT (the best model when it is a
  // field model, else the best field model), or, when that does not identify it and the drives'
  // phases determine it, theirs (delta_t.method, field_status and field_reason).
  // final_fit.model.delta_t_s is the chosen model's own parameter (what the predictor uses); it
  // is the session's dt only when delta_t.identified() by the field model and delta_t.model ==
  // final_fit.model.kind.
  DeltaTEstimate delta_t;
  // dt from the drives' phases on every pose and reading (drive_phase.h): independent of the
  // field models, it brackets dt when no field model is steady over the splits (few poses, a
  // field far from the models), so that the final fit keeps the clocks' valley.
  DrivePhaseEstimate drive_phase;
  DeltaTBracket bracket = DeltaTBracket::kNone;
  // The window final_fit searched for its dt: the search window, the bracket of a steady field
  // model, or, when the sine model is chosen without a bracket, a quarter fast period around
  // delta_t.profile_min_s (sine_in_field_valley): the sine model's dt is defined only modulo half
  // the fast period, and of those valleys the final fit keeps the judged field model's, so that
  // its dt lies in the clocks' most likely valley rather than the one the noise preferred.
  double final_min_s = 0, final_max_s = 0;
  bool sine_in_field_valley = false;
};

// A dt the judged field model identified, contradicted by a determined drive-phase estimate (one
// that does not depend on the field's shape): further apart than
// `o.max_phase_disagreement_sigmas` combined sigmas, one of them is biased (the field model's
// sigma is its splits' scatter, blind to its own misfit: a linear model of a quadratic field,
// with the few poses that leave the quadratic model out, put dt at 0.599 +- 0.008 ms against the
// phases' 0.550 +- 0.002 ms for a truth of 0.550 on an independent simulator's 7-pose folder).
// Then `dt` becomes not identified (imprecise) with both figures in its reason; returns whether.
bool CrossCheckWithDrivePhases(const DrivePhaseEstimate& phases,
                               const DeltaTIdentificationOptions& o, DeltaTEstimate* dt);

// Throws std::invalid_argument naming what is missing or inconsistent.
HallCalibrationResult CalibrateHall(const HallCalibrationInput& input,
                                    const HallCalibrationOptions& options);

// Readings of one recording as (generator time, field) through a time base.
void MapReadings(const dataset::HallRecording& rec, const TimeBase& tb, std::vector<double>* t_s,
                 std::vector<Eigen::Vector3d>* b);

// Live prediction: raw readings (uT, generator time) -> pose. Thread-safe (const).
class HallPredictor {
 public:
  HallPredictor(HallModel model, PhaseProfile background, Eigen::Vector3d actual_mean_uT);
  // Pose (alpha_deg, beta_deg, trans_mm) at generator time t_s - delta_t of a raw reading taken
  // at generator time t_s.
  Eigen::Vector3d Predict(double t_s, const Eigen::Vector3d& raw_uT) const;
  void PredictBatch(const double* t_s, const Eigen::Vector3d* raw_uT, Eigen::Vector3d* pose,
                    size_t n) const;
  const HallModel& model() const { return model_; }
  const PhaseProfile& background() const { return background_; }
  const Eigen::Vector3d& actual_mean_uT() const { return actual_mean_; }

 private:
  HallModel model_;
  PhaseProfile background_;
  Eigen::Vector3d actual_mean_;
  Eigen::Vector3d offset_;  // actual_mean - background mean
  int features_ = 0;
  double a_[3][20] = {};  // model.a, row-major, for a tight inner loop
};

}  // namespace msmcal::hall

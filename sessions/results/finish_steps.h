#pragma once
// The steps after a recorded session, as functions of a session folder that write its results/
// and return what happened: the solve (MSM paper Sec. V-A), the Hall calibration (Sec. V-B) and
// the Hall prediction. `msmcal solve`, `msmcal hall calibrate` and `msmcal hall predict` are thin
// wrappers that print a step's report; the session modes (demo, resume, sweep, replay) call the
// same functions in-process.
//
// A step never prints: what the command line shows is in the result (`warnings`, the lines the
// command writes to stderr; `log`, the lines it logs; `text`, its summary on stdout). Expected
// failures (a folder that cannot be read or solved, a missing prerequisite) are returned in
// `error`, naming the file or the reason; nothing is thrown for them.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/hall/calibration.h"
#include "processing/solver/pipeline.h"
#include "sessions/results/results_files.h"

namespace msmcal::results {

struct StepLogLine {
  enum class Level { kInfo, kWarning };
  Level level = Level::kInfo;
  std::string text;
};

struct StepReport {
  std::string error;                  // empty: the step succeeded
  std::vector<std::string> warnings;  // stderr lines, in order (may hold several lines each)
  std::vector<StepLogLine> log;       // log lines, in order
  std::string text;                   // the summary printed on success (ends with '\n')
  bool ok() const { return error.empty(); }
};

// ------------------------------------------------------------------------------------- solve

struct SolveStepResult : StepReport {
  MirrorPosesSummary summary;  // as written to results/summary.json (when ok)
};
// Reads `dir` (session.yaml, camera.yaml and the images, never hall/ or marg/), solves it with
// `options` and writes results/: solve_options.yaml (first, the values used), mirror_planes.csv,
// beams.csv, validation.csv, validation_detail.csv, validation_dots.csv, residuals.csv,
// summary.json "mirror_poses", detections.csv and diagnostics/ (the annotated dropped and partly
// used frames; also when the solve fails with a partial result). `options` must be valid
// (PipelineOptions::Validate()), else it is the error. `on_image` (optional; called from the
// solver's image threads, so it must be thread-safe): after each image read, the number of distinct
// images read so far and the session's frame count (progress lines; later passes re-read images
// without adding to the count).
SolveStepResult RunSolveStep(
    const std::filesystem::path& dir, const solver::PipelineOptions& options,
    const std::function<void(size_t images_read, size_t images_total)>& on_image = {});

// ---------------------------------------------------------------------------- Hall calibration

// The calibration input of a folder: both Hall recordings and the solver's poses.
struct HallCalibrationSetup {
  dataset::HallRecording actual;
  dataset::HallRecording background;
  double pattern_period_s = 0;
  double fast_frequency_hz = 0;
  double slow_frequency_hz = 0;
  std::vector<hall::PoseSample> poses;
  // The calibration input; it points into this object.
  hall::HallCalibrationInput Input() const;
};
// Throws std::runtime_error naming what is missing (dir/hall/actual.csv, dir/hall/background.csv,
// no mirror planes).
HallCalibrationSetup MakeHallCalibrationSetup(const dataset::Recording& rec,
                                              const std::vector<dataset::MirrorPlaneRow>& planes,
                                              const std::string& dir_for_messages);
// Table II as text (one row per model fitted, the models left out, the paper's figures).
std::string FormatTableTwo(const hall::HallCalibrationResult& result,
                           const hall::HallCalibrationOptions& options);

struct HallCalibrationStepResult : StepReport {
  std::filesystem::path model_file;  // results/hall_model.yaml (when ok)
  hall::HallModelKind model = hall::HallModelKind::kLinear;
  double delta_t_s = 0;  // the chosen model's own dt (hall_model.yaml delta_t_s)
  // The session's dt (hall_model.yaml time_offset): identified or not, and why.
  hall::DeltaTEstimate time_offset;
};
// The text lines of `estimate` (`model_delta_t_s`: the chosen model's own dt, `model` its kind;
// `in_field_valley`: that dt was searched in the judged field model's valley,
// HallCalibrationResult::sine_in_field_valley):
// "delta_t = 0.5474 ms +- 0.0052 ms (cubic model, identified: ...)" or
// "delta_t not identified (splits disagree): ...".
std::string FormatDeltaT(const hall::DeltaTEstimate& estimate, hall::HallModelKind model,
                         double model_delta_t_s, bool in_field_valley = false);
// The line of the drives' dt (hall::DrivePhaseEstimate): "drive phases: dt = 0.5512 ms +-
// 0.0031 ms (...)" or "drive phases: dt not determined (<reason>)".
std::string FormatDrivePhase(const hall::DrivePhaseEstimate& estimate, hall::DeltaTBracket bracket);
// Fits the Hall models and delta_t on `dir` (needs results/mirror_planes.csv from the solve) and
// writes results/hall_model.yaml. `text`: Table II, the clock figures and the chosen model.
HallCalibrationStepResult RunHallCalibration(const std::filesystem::path& dir,
                                             const hall::HallCalibrationOptions& options);

// ----------------------------------------------------------------------------- Hall prediction

struct HallPredictionStepResult : StepReport {
  size_t poses = 0;
};
// Maps the readings of `readings_csv` to poses with the model of `model_file` and writes
// `poses_csv` (results/hall_poses.csv format). The time base is fitted on `clock_csv`; empty:
// the readings' sibling <stem>_clock.csv when it exists, else the calibration session's time
// base (said in `log` as a warning).
HallPredictionStepResult RunHallPrediction(const std::filesystem::path& model_file,
                                           const std::filesystem::path& readings_csv,
                                           const std::filesystem::path& poses_csv,
                                           const std::filesystem::path& clock_csv = {});

}  // namespace msmcal::results

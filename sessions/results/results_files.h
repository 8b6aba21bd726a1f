#pragma once
// Typed readers and writers of a session folder's results/ (../shared/docs/interchange-format.md,
// "results/"): the solver's mirror_planes.csv, beams.csv, validation.csv, validation_detail.csv
// and its "mirror_poses" key of summary.json; the Hall calibration's hall_model.yaml and the
// predictor's hall_poses.csv. These files are a contract with other tools: the writers produce
// exactly the bytes they always have (numbers in the shortest round-trip form), the readers are
// strict (interchange::CsvReader: fixed header, every cell a finite number).
//
// Errors: readers throw interchange::InterchangeError naming the file and the line and column
// (CSV: "results/hall_poses.csv:12: column 't_s': 'x' is not a number") or the key (JSON/YAML:
// "results/summary.json: mirror_poses.validation_rms_deg: missing"). Writers replace the file
// atomically and throw std::runtime_error naming it.

#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/hall/calibration.h"
#include "processing/solver/solve_types.h"

namespace msmcal::results {

// ---------------------------------------------------------------------------- solver CSVs

// results/mirror_planes.csv: j,t_s,nx,ny,nz,d_mm,alpha_deg,beta_deg,trans_mm,sigma_alpha_deg,
// sigma_beta_deg,sigma_trans_mm.
std::vector<dataset::MirrorPlaneRow> ReadMirrorPlanesCsv(const std::filesystem::path& file);
void WriteMirrorPlanesCsv(const std::filesystem::path& file,
                          const std::vector<dataset::MirrorPlaneRow>& rows);
// results/beams.csv: beam,px,py,pz,vx,vy,vz.
std::vector<dataset::BeamRow> ReadBeamsCsv(const std::filesystem::path& file);
void WriteBeamsCsv(const std::filesystem::path& file, const std::vector<dataset::BeamRow>& rows);
// results/validation.csv: beam,j,err_px,err_deg.
std::vector<dataset::ValidationRow> ReadValidationCsv(const std::filesystem::path& file);
void WriteValidationCsv(const std::filesystem::path& file,
                        const std::vector<dataset::ValidationRow>& rows);
// The three above on text (`display_name` stands for the file in messages):
// ParseXCsv(FormatXCsv(rows), name) == rows.
std::vector<dataset::MirrorPlaneRow> ParseMirrorPlanesCsv(const std::string& text,
                                                          const std::string& display_name);
std::vector<dataset::BeamRow> ParseBeamsCsv(const std::string& text,
                                            const std::string& display_name);
std::vector<dataset::ValidationRow> ParseValidationCsv(const std::string& text,
                                                       const std::string& display_name);
std::string FormatMirrorPlanesCsv(const std::vector<dataset::MirrorPlaneRow>& rows);
std::string FormatBeamsCsv(const std::vector<dataset::BeamRow>& rows);
std::string FormatValidationCsv(const std::vector<dataset::ValidationRow>& rows);

// results/validation_detail.csv (native): per held-out dot, the proposed and the baseline error,
// the predicted sigma and the error normalised by it.
struct ValidationDetailRow {
  int beam = 0;
  int j = 0;
  double err_px = 0, err_deg = 0;
  double baseline_err_px = 0, baseline_err_deg = 0;
  double predicted_sigma_px = 0;
  double normalised_error = 0;
};
std::vector<ValidationDetailRow> ValidationDetailRows(
    const std::vector<solver::ValidationDetail>& validation);
std::vector<ValidationDetailRow> ReadValidationDetailCsv(const std::filesystem::path& file);
void WriteValidationDetailCsv(const std::filesystem::path& file,
                              const std::vector<ValidationDetailRow>& rows);
std::vector<ValidationDetailRow> ParseValidationDetailCsv(const std::string& text,
                                                          const std::string& display_name);
std::string FormatValidationDetailCsv(const std::vector<ValidationDetailRow>& rows);

// results/validation_dots.csv (native): per held-out dot, in validation_detail.csv's order, where
// it is on the image (px, (0, 0) at the centre of the top-left pixel) as measured and as the
// proposed model predicts it, the 2x2 covariance of their difference (eq. 10, px^2) and the error
// whitened jointly over every held-out dot (solver::ValidationDetail::joint_whitened).
struct ValidationDotRow {
  int beam = 0;
  int j = 0;
  Eigen::Vector2d observed_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d predicted_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov_px2 = Eigen::Matrix2d::Zero();
  Eigen::Vector2d joint_whitened = Eigen::Vector2d::Zero();
};
std::vector<ValidationDotRow> ValidationDotRows(
    const std::vector<solver::ValidationDetail>& validation);
std::vector<ValidationDotRow> ReadValidationDotsCsv(const std::filesystem::path& file);
void WriteValidationDotsCsv(const std::filesystem::path& file,
                            const std::vector<ValidationDotRow>& rows);
std::vector<ValidationDotRow> ParseValidationDotsCsv(const std::string& text,
                                                     const std::string& display_name);
std::string FormatValidationDotsCsv(const std::vector<ValidationDotRow>& rows);

// results/residuals.csv (native): every residual the MLE fitted, whitened by the covariance it
// used (solver::WhitenedResidual): family (solver::MleFamily: 0 corners_c1_world,
// 1 corners_c1_sliding, 2 corners_c2_world, 3 sliding_dots, 4 reflected_dots,
// 5 reflected_dots_near_edge), group (corner set, sliding pose or mirror plane), the observed
// pixel and the two whitened components.
std::vector<solver::WhitenedResidual> ReadResidualsCsv(const std::filesystem::path& file);
void WriteResidualsCsv(const std::filesystem::path& file,
                       const std::vector<solver::WhitenedResidual>& rows);
std::vector<solver::WhitenedResidual> ParseResidualsCsv(const std::string& text,
                                                        const std::string& display_name);
std::string FormatResidualsCsv(const std::vector<solver::WhitenedResidual>& rows);
// Each native CSV above and hall_poses.csv below has a text entry point beside its file one,
// as the three interchange CSVs have (the fuzz target fuzz/results_csv_fuzz.cc uses them):
// Parse*Csv(text, display_name) reads what Read*Csv reads (`display_name` stands for the file
// in messages); Format*Csv(rows) is the text Write*Csv writes, and
// Parse*Csv(Format*Csv(rows), name) gives rows back.

// ------------------------------------------------------------------- summary.json mirror_poses

// The solver's figures under summary.json's "mirror_poses" key (other producers own other keys).
struct MirrorPosesSummary {
  double solve_time_s = 0, ceres_time_s = 0;
  int ceres_iterations = 0;
  int planes_scan = 0, planes_fast_only = 0, planes_neutral = 0;
  int beams = 0;
  double mean_spanning_angle_deg = 0;
  double validation_rms_deg = 0, validation_rms_px = 0;
  double baseline_validation_rms_deg = 0, baseline_validation_rms_px = 0;
  double validation_normalised_rms = 0;
  int validation_count = 0;
  double corner_variance_factor = 0, dot_variance_factor = 0;
  // Variance-component estimation per residual family (solver::MleFamilyName): the posterior
  // factor on its input covariance and its redundancy.
  struct Family {
    std::string name;
    double variance_factor = 0, redundancy = 0;
  };
  std::vector<Family> variance_factors;
  Eigen::Vector3d mirror0_sigma_rotation_deg = Eigen::Vector3d::Zero();
  Eigen::Vector3d mirror0_sigma_origin_mm = Eigen::Vector3d::Zero();
  double rms_sigma_alpha_deg = 0, rms_sigma_beta_deg = 0, rms_sigma_trans_mm = 0;
  // In {W}, from the MLE's covariance: each beam's direction (RMS angle, sqrt of the trace of its
  // 2x2 tangent block; estimate and validate beams, beams.csv's order) and every mirror plane's
  // normal (RMS over the planes). Step 1's sliding-plate depths set a common tilt of the beams
  // that step 2 cannot see (docs/solver.md, "What limits the beams"); these carry it, where
  // the {0}-frame sigmas above do not. Empty / < 0 in summaries written before session 24.
  std::vector<double> beam_direction_sigma_deg;
  double rms_sigma_normal_world_deg = -1;
  std::vector<solver::DroppedFrame> dropped_frames;
  std::vector<std::string> notes;
  Eigen::Matrix3d world_from_mirror0_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d world_from_mirror0_translation = Eigen::Vector3d::Zero();
};
MirrorPosesSummary SummariseSolve(const solver::SolveOutput& out, double solve_time_s);
// Replaces the "mirror_poses" key of `file` (created if absent; an unreadable file is replaced),
// keeping the other keys. JSON with two-space indent, keys sorted.
void WriteMirrorPosesSummary(const std::filesystem::path& file, const MirrorPosesSummary& summary);
// results/summary.json is shared by several result producers (mirror_poses, hall, provenance):
// each replaces its own top-level `key` only and keeps the others; a file that is not a JSON
// object is replaced; unchanged content is not rewritten.
void UpdateSummaryJson(const std::filesystem::path& file, const std::string& key,
                       nlohmann::json value);
// Every field is required; a JSON null (how a non-finite number is written) reads as NaN.
// Whether results/summary.json has the top-level `section` ("mirror_poses", "hall"); false when
// the file does not exist. Throws naming the file when it is not a JSON object.
bool SummaryJsonHas(const std::filesystem::path& file, const std::string& section);
MirrorPosesSummary ReadMirrorPosesSummary(const std::filesystem::path& file);

// ----------------------------------------------------------------------------- Hall results

// results/summary.json "hall" (written by `msmcal hall calibrate`, keeping the other keys): the
// chosen model, the poses it was fitted to, its test and train RMS per output, its own dt
// (model_delta_t_s, what the predictor uses), and the session's dt: delta_t_s and
// delta_t_sigma_s (null unless delta_t_identified), delta_t_status, delta_t_model (the judged
// field model), delta_t_profile_min_s (that model's cost minimum: the candidate when dt is not
// identified) and delta_t_reason; actual_readings_used.
void WriteHallSummary(const std::filesystem::path& file, const hall::HallCalibrationResult& result,
                      size_t poses);

// results/hall_model.yaml (format msmcal-hall-model/1): model kind, parameters, delta_t_s,
// train/test RMS per output, the Table II comparison, the time base and background profile, and
// (since issue 15; optional for readers) time_offset: whether the recording determines the
// session's dt (hall::DeltaTEstimate). delta_t_s is the chosen model's own dt, what the
// predictor uses; the session's dt is time_offset.delta_t_s, written only when
// time_offset.identified is true (a sine model's dt aligns phases; a short recording leaves dt
// ambiguous). A file without time_offset is from before: its delta_t_s was reported as dt.
std::string FormatHallModelYaml(const hall::HallCalibrationResult& result,
                                const hall::HallCalibrationOptions& options);
struct HallModelFile {
  hall::HallModel model;
  hall::TimeBase time_base;  // offset, rate, pattern period
  hall::PhaseProfile background;
  Eigen::Vector3d actual_mean_uT = Eigen::Vector3d::Zero();
  // The final model's mean test RMS over the splits (alpha deg, beta deg, trans mm); absent when
  // the file has no test_rms.
  std::optional<Eigen::Vector3d> test_rms;
  // time_offset (absent in files written before it): status, model, reason, and the figures
  // written (delta_t_s and sigma_s when identified; NaN when a figure is absent).
  std::optional<hall::DeltaTEstimate> time_offset;
  // protocol.evaluation and .repetitions: how the comparison was evaluated. Files written
  // before session 22 have no evaluation: random splits.
  bool leave_one_out = false;
  int repetitions = 0;  // 0: not written
};
// Errors name the file and the field: "hall_model.yaml: field 'delta_t_s': expected a number
// (line 3)".
HallModelFile ReadHallModelYaml(const std::filesystem::path& file);
// The same on the file's text (`file` names it in messages).
HallModelFile ParseHallModelYaml(const std::string& text, const std::string& file);

// results/hall_poses.csv: mcu_time_us,t_s,alpha_deg,beta_deg,trans_mm (t_s: generator time of
// the pose, i.e. of the reading minus the model's delta_t).
struct HallPoseRow {
  double mcu_time_us = 0;
  double t_s = 0;
  double alpha_deg = 0, beta_deg = 0, trans_mm = 0;
};
std::vector<HallPoseRow> ReadHallPosesCsv(const std::filesystem::path& file);
void WriteHallPosesCsv(const std::filesystem::path& file, const std::vector<HallPoseRow>& rows);
std::vector<HallPoseRow> ParseHallPosesCsv(const std::string& text,
                                           const std::string& display_name);
std::string FormatHallPosesCsv(const std::vector<HallPoseRow>& rows);

}  // namespace msmcal::results

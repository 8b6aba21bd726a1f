#pragma once
// The calibration report of a session folder (issue 18): the verdict first (verdict.h), the
// Table I-style figures (baseline and proposed), the Table II-style comparison of Hall models and
// the MARG costs as HTML tables, interactive plots (report_html.h) and the provenance
// (provenance.h); as text (printed by the session modes) and as one offline HTML page.
//
// Everything comes from the folder: session.yaml and the Hall recordings, results/ (the solver's
// files, the Hall calibration, results/hall_poses.csv, results/marg_calibration.yaml), the
// journal session.db and, through a TruthSource, a ground truth (simulated sessions only: the
// simulation layer reads truth/, simulation/truth). A part whose files are missing is listed in
// `skipped`, never estimated.

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "sessions/report/provenance.h"
#include "sessions/report/report_html.h"
#include "sessions/report/verdict.h"
#include "sessions/results/results_files.h"

namespace msmcal::report {

struct SessionReport {
  // Table I style.
  bool have_planes = false;
  int planes = 0;
  int triggers_planned = 0;
  double normal_rms_vs_truth_deg = 0;  // angle between estimated and true plane normals
  double alpha_rms_vs_truth_deg = 0, beta_rms_vs_truth_deg = 0, trans_rms_vs_truth_mm = 0;
  double validation_rms_deg = 0, validation_rms_px = 0;
  double baseline_rms_deg = 0, baseline_rms_px = 0;
  double normalised_validation_rms = 0;
  double mean_spanning_angle_deg = 0;
  int validation_count = 0;
  // Table II style.
  bool have_hall = false;
  std::string hall_model;
  double delta_t_s = 0, delta_t_sigma_s = 0, delta_t_truth_s = 0;
  // hall_model.yaml time_offset: false when the recording does not determine dt (delta_t_s and
  // delta_t_sigma_s are then NaN, delta_t_reason says why).
  bool delta_t_identified = true;
  std::string delta_t_reason;
  double test_rms[3] = {0, 0, 0};  // alpha deg, beta deg, trans mm
  bool have_noise_floor = false;
  double noise_floor[3] = {0, 0, 0};     // single-reading noise through the model, same units
  bool noise_floor_from_linear = false;  // the model ignores the field (sine): via the linear one
  double reading_noise_uT[3] = {0, 0, 0};
  bool have_hall_vs_truth = false;
  double hall_rms_vs_truth[3] = {0, 0, 0};  // predicted pose vs true trajectory

  std::vector<VerdictLine> verdict;
  Provenance provenance;
  std::vector<Table> tables;
  std::vector<Chart> charts;
  std::vector<std::string> skipped;
  std::string text;  // the printed report (verdict lines included)
  std::string html;  // self-contained page
};

// A session's ground truth as the report compares the results with it. BuildSessionReport calls
// CompareMirrorPlanes (when the solver's planes are there) before CompareHallPoses (when the Hall
// prediction is there and HasPoseTrajectory()); each fills the *_vs_truth figures of `report` and
// adds its plots to `charts` (a truth series goes into the chart "plot-scan-pattern" when it is
// there).
class TruthComparison {
 public:
  virtual ~TruthComparison() = default;
  // `planes`: results/mirror_planes.csv.
  virtual void CompareMirrorPlanes(const std::vector<dataset::MirrorPlaneRow>& planes,
                                   SessionReport* report, std::vector<Chart>* charts) = 0;
  virtual double TrueDeltaT() const = 0;  // s
  virtual bool HasPoseTrajectory() const = 0;
  // `rows`: results/hall_poses.csv.
  virtual void CompareHallPoses(const std::vector<results::HallPoseRow>& rows,
                                SessionReport* report, std::vector<Chart>* charts) = 0;
};
// The truth of a session folder, or null when it has none. Throws std::runtime_error naming a
// truth file that cannot be parsed.
using TruthSource =
    std::function<std::unique_ptr<TruthComparison>(const std::filesystem::path& dir)>;

struct ReportOptions {
  // This process ran the session (demo, session run, resume, sweep): its provenance is the
  // session's. False for `msmcal report DIR` (the stored provenance is kept).
  bool session_process = true;
  std::vector<std::string> session_notes;  // the session's log lines (shown folded)
};

// Reads `dir` and builds the report; `truth` may be empty (no comparison with a truth). Throws
// std::runtime_error naming a file that exists but cannot be parsed. Writes the provenance into
// results/summary.json (ResolveProvenance).
SessionReport BuildSessionReport(const std::filesystem::path& dir, const ReportOptions& options,
                                 const TruthSource& truth);

// BuildSessionReport, then writes dir/report.html (atomically). Returns the report.
SessionReport WriteSessionReport(const std::filesystem::path& dir, const ReportOptions& options,
                                 const TruthSource& truth);

}  // namespace msmcal::report

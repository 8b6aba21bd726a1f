#pragma once
// The calibration report of a solved session folder: Table I-style figures (mirror-plane
// normal error against the simulator's truth, baseline vs proposed validation-beam error) and
// Table II-style figures (Hall model, test RMS, delta_t against truth), as text and as a
// self-contained HTML page with inline SVG plots (scan pattern of dots, validation residual
// histogram, predicted sigma vs error, Hall model prediction vs true pose).
//
// Everything comes from the folder: results/ (solver, Hall calibration, optional
// results/hall_poses.csv from `msmcal hall predict`) and, through a TruthSource, a ground truth
// (simulated sessions only: the simulation layer reads truth/, simulation/truth). A part whose
// files are missing is listed in `skipped`, never estimated.

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "sessions/results/results_files.h"

namespace msmcal::orchestrator {

struct SessionReport {
  // Table I style.
  bool have_planes = false;
  int planes = 0;
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
  double delta_t_s = 0, delta_t_truth_s = 0;
  double test_rms[3] = {0, 0, 0};  // alpha deg, beta deg, trans mm
  bool have_hall_vs_truth = false;
  double hall_rms_vs_truth[3] = {0, 0, 0};  // predicted pose vs true trajectory
  std::vector<std::string> skipped;
  std::string text;  // the printed report
  std::string html;  // self-contained page
};

// A session's ground truth as the report compares the results with it. BuildSessionReport calls
// CompareMirrorPlanes (when the solver's planes are there) before CompareHallPoses (when the Hall
// prediction is there and HasPoseTrajectory()); each fills the *_vs_truth figures of `report` and
// appends its plots (SVG) to `plots`.
class TruthComparison {
 public:
  virtual ~TruthComparison() = default;
  // `planes`: results/mirror_planes.csv.
  virtual void CompareMirrorPlanes(const std::vector<dataset::MirrorPlaneRow>& planes,
                                   SessionReport* report, std::vector<std::string>* plots) = 0;
  virtual double TrueDeltaT() const = 0;  // s
  virtual bool HasPoseTrajectory() const = 0;
  // `rows`: results/hall_poses.csv.
  virtual void CompareHallPoses(const std::vector<results::HallPoseRow>& rows,
                                SessionReport* report, std::vector<std::string>* plots) = 0;
};
// The truth of a session folder, or null when it has none. Throws std::runtime_error naming a
// truth file that cannot be parsed.
using TruthSource =
    std::function<std::unique_ptr<TruthComparison>(const std::filesystem::path& dir)>;

// Reads `dir` and builds the report; `truth` may be empty (no comparison with a truth). Throws
// std::runtime_error naming a file that exists but cannot be parsed.
SessionReport BuildSessionReport(const std::filesystem::path& dir,
                                 const std::vector<std::string>& session_notes,
                                 const TruthSource& truth);

// A minimal SVG plot (exposed for tests): series of points or polylines on linear axes.
struct PlotSeries {
  std::string name;
  std::vector<double> x, y;
  bool line = false;
  std::string colour = "#1f77b4";
};
std::string SvgPlot(const std::string& title, const std::string& x_label,
                    const std::string& y_label, const std::vector<PlotSeries>& series,
                    bool y_down = false);
std::string SvgHistogram(const std::string& title, const std::string& x_label,
                         const std::vector<double>& values, int bins);

}  // namespace msmcal::orchestrator

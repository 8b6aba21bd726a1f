#pragma once
// The summary table at the end of a sweep: one row per point with its values, status and the
// figures read back from the point's session folder (session_log.txt, results/summary.json of
// `msmcal solve`, results/hall_model.yaml of `msmcal hall calibrate`).

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "sessions/sweep/sweep_plan.h"
#include "sessions/sweep/sweep_state.h"

namespace msmcal::sweep {

struct PointFigures {
  size_t frames_accepted = 0, frames_rejected = 0;
  std::optional<uint64_t> hall_lost;         // Hall readings lost (both recordings)
  std::optional<double> validation_rms_deg;  // summary.json mirror_poses.validation_rms_deg
  std::optional<double> validation_rms_px;   // ... validation_rms_px
  std::optional<double> baseline_rms_deg;    // ... baseline_validation_rms_deg
  std::string hall_model;                    // hall_model.yaml model ("" when absent)
  std::optional<double> hall_rms_alpha_deg, hall_rms_beta_deg,
      hall_rms_trans_mm;  // test_rms
                          // (train_rms when no test split was run)
  // The session's dt: hall_model.yaml time_offset.delta_t_s when identified (delta_t_s in files
  // without time_offset); absent when time_offset says it is not identified, with the reason.
  std::optional<double> hall_delta_t_s;
  std::optional<std::string> hall_delta_t_not_identified;
  // Against the simulator's truth (simulated sessions; filled by the runner's `augment` hook from
  // the session report): plane normal error RMS, Hall-predicted pose vs true pose RMS.
  std::optional<double> normal_rms_vs_truth_deg;
  std::optional<double> hall_vs_truth_alpha_deg, hall_vs_truth_beta_deg, hall_vs_truth_trans_mm;
};
// Reads what exists; missing files leave fields empty; unreadable files leave them empty too
// (the summary must never stop a sweep).
PointFigures ReadPointFigures(const std::filesystem::path& folder);

struct SummaryRow {
  SweepPoint point;
  PointRecord record;
  PointFigures figures;
};

// CSV (header + one line per point): point, one column per axis path, repeat, seed, status,
// reason, frames_accepted, frames_rejected, hall_lost, validation_rms_deg, validation_rms_px,
// baseline_rms_deg, normal_rms_vs_truth_deg, hall_model, hall_rms_alpha_deg, hall_rms_beta_deg,
// hall_rms_trans_mm, hall_delta_t_ms, hall_vs_truth_alpha_deg, hall_vs_truth_beta_deg,
// hall_vs_truth_trans_mm, duration_s. Empty cells for absent figures; RFC 4180 quoting.
std::string SummaryCsv(const SweepPlan& plan, const std::vector<SummaryRow>& rows);
// The same as an aligned text table for the terminal, with a last line counting done / failed.
std::string SummaryTable(const SweepPlan& plan, const std::vector<SummaryRow>& rows);

}  // namespace msmcal::sweep

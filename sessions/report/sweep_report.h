#pragma once
// The report of a sweep folder (sessions/sweep: sweep.yaml, sweep_state.json, one session folder
// per point): a verdict (points done, each point's own verdict), a table of the points linking
// every point's report.html, and plots of the plane-normal error, the validation error, the Hall
// test RMS and delta_t against each swept setting.

#include <filesystem>
#include <string>
#include <vector>

#include "sessions/report/session_report.h"
#include "sessions/sweep/sweep_plan.h"

namespace msmcal::report {

struct SweepReport {
  int points = 0, done = 0, reported = 0;
  std::vector<VerdictLine> verdict;
  std::vector<Chart> charts;
  std::string text, html;
};

// Reads `dir` (the plan's points, sweep_state.json) and every point's folder. With
// `write_point_reports`, first (re)writes each point's report.html (WriteSessionReport with
// `point_options`); else reads the figures without writing. A point whose report cannot be built
// is listed with the reason, never stops the sweep report.
SweepReport BuildSweepReport(const std::filesystem::path& dir, const sweep::SweepPlan& plan,
                             const std::vector<sweep::SweepPoint>& points, const TruthSource& truth,
                             bool write_point_reports, const ReportOptions& point_options);
// BuildSweepReport, then writes dir/report.html.
SweepReport WriteSweepReport(const std::filesystem::path& dir, const sweep::SweepPlan& plan,
                             const std::vector<sweep::SweepPoint>& points, const TruthSource& truth,
                             bool write_point_reports, const ReportOptions& point_options);

}  // namespace msmcal::report

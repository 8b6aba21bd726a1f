#include "sessions/orchestrator/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "sessions/results/results_files.h"
#include "sessions/store/session_store.h"

namespace msmcal::orchestrator {

namespace fs = std::filesystem;

namespace {

std::string Fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

std::string Escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<')
      o += "&lt;";
    else if (c == '>')
      o += "&gt;";
    else if (c == '&')
      o += "&amp;";
    else
      o += c;
  }
  return o;
}

// The Hall readings the recorder dropped on queue overflow (journal meta
// hall.<name>.readings_dropped, written by the orchestrator); empty when there is no journal.
std::string HallDroppedLine(const fs::path& dir) {
  if (!fs::exists(dir / store::kSessionDbName)) return "";
  std::string line = "Hall readings dropped (recorder queue full):";
  try {
    const store::SystemClock clock;
    const auto journal = store::SessionStore::Open(dir, clock, /*read_only=*/true);
    bool any = false;
    for (const char* name : {"background", "actual"}) {
      if (const auto v = journal->GetMeta(std::string("hall.") + name + ".readings_dropped")) {
        line += std::string(any ? "," : "") + " " + name + " " + *v;
        any = true;
      }
    }
    if (!any) line += " not recorded in the journal";
  } catch (const std::exception& e) {
    line += std::string(" journal unreadable: ") + e.what();
  }
  return line + "\n";
}

}  // namespace

std::string SvgPlot(const std::string& title, const std::string& x_label,
                    const std::string& y_label, const std::vector<PlotSeries>& series,
                    bool y_down) {
  const double w = 560, h = 380, l = 70, r = 20, t = 30, b = 50;
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  for (const auto& s : series) {
    for (double x : s.x) x0 = std::min(x0, x), x1 = std::max(x1, x);
    for (double y : s.y) y0 = std::min(y0, y), y1 = std::max(y1, y);
  }
  if (!(x1 >= x0)) x0 = 0, x1 = 1;
  if (!(y1 >= y0)) y0 = 0, y1 = 1;
  if (x1 == x0) x1 = x0 + 1;
  if (y1 == y0) y1 = y0 + 1;
  auto px = [&](double x) { return l + (x - x0) / (x1 - x0) * (w - l - r); };
  auto py = [&](double y) {
    const double f = (y - y0) / (y1 - y0);
    return y_down ? t + f * (h - t - b) : h - b - f * (h - t - b);
  };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << w << "' height='" << h
    << "' font-family='sans-serif' font-size='11'>";
  o << "<rect x='" << l << "' y='" << t << "' width='" << (w - l - r) << "' height='" << (h - t - b)
    << "' fill='none' stroke='#888'/>";
  o << "<text x='" << w / 2 << "' y='18' text-anchor='middle' font-size='13'>" << Escape(title)
    << "</text>";
  o << "<text x='" << w / 2 << "' y='" << h - 10 << "' text-anchor='middle'>" << Escape(x_label)
    << "</text>";
  o << "<text x='14' y='" << h / 2 << "' text-anchor='middle' transform='rotate(-90 14 " << h / 2
    << ")'>" << Escape(y_label) << "</text>";
  for (int k = 0; k <= 4; ++k) {
    const double xv = x0 + (x1 - x0) * k / 4, yv = y0 + (y1 - y0) * k / 4;
    o << "<text x='" << px(xv) << "' y='" << h - b + 14 << "' text-anchor='middle'>"
      << Fmt("%.4g", xv) << "</text>";
    o << "<text x='" << l - 4 << "' y='" << py(yv) + 4 << "' text-anchor='end'>" << Fmt("%.4g", yv)
      << "</text>";
  }
  int legend = 0;
  for (const auto& s : series) {
    const size_t n = std::min(s.x.size(), s.y.size());
    if (s.line) {
      o << "<polyline fill='none' stroke='" << s.colour << "' stroke-width='1.2' points='";
      for (size_t i = 0; i < n; ++i)
        o << Fmt("%.1f", px(s.x[i])) << ',' << Fmt("%.1f", py(s.y[i])) << ' ';
      o << "'/>";
    } else {
      for (size_t i = 0; i < n; ++i)
        o << "<circle cx='" << Fmt("%.1f", px(s.x[i])) << "' cy='" << Fmt("%.1f", py(s.y[i]))
          << "' r='2' fill='" << s.colour << "'/>";
    }
    if (!s.name.empty()) {
      o << "<text x='" << l + 8 << "' y='" << t + 14 + 13 * legend << "' fill='" << s.colour << "'>"
        << Escape(s.name) << "</text>";
      ++legend;
    }
  }
  o << "</svg>";
  return o.str();
}

std::string SvgHistogram(const std::string& title, const std::string& x_label,
                         const std::vector<double>& values, int bins) {
  PlotSeries s;
  s.line = true;
  if (values.empty() || bins < 1) return SvgPlot(title, x_label, "count", {});
  const double lo = *std::min_element(values.begin(), values.end());
  double hi = *std::max_element(values.begin(), values.end());
  if (hi <= lo) hi = lo + 1;
  std::vector<int> counts(bins, 0);
  for (double v : values)
    ++counts[std::min(bins - 1, static_cast<int>((v - lo) / (hi - lo) * bins))];
  for (int k = 0; k < bins; ++k) {  // outline of the bars
    const double a = lo + (hi - lo) * k / bins, b = lo + (hi - lo) * (k + 1) / bins;
    s.x.insert(s.x.end(), {a, a, b, b});
    s.y.insert(s.y.end(), {0.0, double(counts[k]), double(counts[k]), 0.0});
  }
  return SvgPlot(title, x_label, "count", {s});
}

SessionReport BuildSessionReport(const fs::path& dir, const std::vector<std::string>& session_notes,
                                 const TruthSource& truth_source) {
  SessionReport rep;
  const fs::path res = dir / "results";
  const std::unique_ptr<TruthComparison> truth = truth_source ? truth_source(dir) : nullptr;
  const bool have_truth = truth != nullptr;
  if (!have_truth)
    rep.skipped.push_back("comparison with truth: no truth/ folder (not a simulated session)");

  std::vector<std::string> plots;
  // Table I: planes vs truth, validation.
  if (fs::exists(res / "mirror_planes.csv") && fs::exists(res / "summary.json")) {
    rep.have_planes = true;
    const auto planes = results::ReadMirrorPlanesCsv(res / "mirror_planes.csv");
    rep.planes = static_cast<int>(planes.size());
    const results::MirrorPosesSummary s = results::ReadMirrorPosesSummary(res / "summary.json");
    rep.validation_rms_deg = s.validation_rms_deg;
    rep.validation_rms_px = s.validation_rms_px;
    rep.baseline_rms_deg = s.baseline_validation_rms_deg;
    rep.baseline_rms_px = s.baseline_validation_rms_px;
    rep.normalised_validation_rms = s.validation_normalised_rms;
    rep.mean_spanning_angle_deg = s.mean_spanning_angle_deg;
    rep.validation_count = s.validation_count;
    if (have_truth) truth->CompareMirrorPlanes(planes, &rep, &plots);
    if (fs::exists(res / "validation_detail.csv")) {
      const auto rows = results::ReadValidationDetailCsv(res / "validation_detail.csv");
      std::vector<double> err;
      PlotSeries sc{"validation dots", {}, {}, false, "#9467bd"};
      for (const auto& r : rows) {
        err.push_back(r.err_px);
        sc.x.push_back(r.predicted_sigma_px);
        sc.y.push_back(r.err_px);
      }
      plots.push_back(
          SvgHistogram("Validation-beam residuals (proposed model)", "error (px)", err, 20));
      plots.push_back(SvgPlot("Uncertainty: predicted sigma vs actual error",
                              "predicted sigma (px)", "error (px)", {sc}));
    } else {
      rep.skipped.push_back("residual plots: results/validation_detail.csv missing");
    }
  } else {
    rep.skipped.push_back(
        "Table I figures: results/mirror_planes.csv or summary.json missing "
        "(solver did not run or failed)");
  }

  // Table II: Hall model.
  const fs::path hall_yaml = res / "hall_model.yaml";
  if (fs::exists(hall_yaml)) {
    rep.have_hall = true;
    const results::HallModelFile model = results::ReadHallModelYaml(hall_yaml);
    rep.hall_model = hall::ToString(model.model.kind);
    rep.delta_t_s = model.model.delta_t_s;
    if (model.test_rms)
      for (int k = 0; k < 3; ++k) rep.test_rms[k] = (*model.test_rms)[k];
    rep.delta_t_truth_s = have_truth ? truth->TrueDeltaT() : 0.0;
    if (have_truth && fs::exists(res / "hall_poses.csv") && truth->HasPoseTrajectory()) {
      truth->CompareHallPoses(results::ReadHallPosesCsv(res / "hall_poses.csv"), &rep, &plots);
    } else {
      rep.skipped.push_back("Hall prediction vs truth: results/hall_poses.csv or truth missing");
    }
  } else {
    rep.skipped.push_back(
        "Table II figures: results/hall_model.yaml missing (Hall calibration "
        "did not run or failed)");
  }

  // Text.
  std::ostringstream t;
  t << "== Table I style: mirror poses ==\n";
  if (rep.have_planes) {
    t << "  scan planes solved:                 " << rep.planes << "\n";
    t << "  mean spanning angle:                " << Fmt("%.2f deg", rep.mean_spanning_angle_deg)
      << "\n";
    t << "  validation-beam error, baseline:    " << Fmt("%.4f deg", rep.baseline_rms_deg)
      << Fmt(" (%.3f px) RMS\n", rep.baseline_rms_px);
    t << "  validation-beam error, proposed:    " << Fmt("%.4f deg", rep.validation_rms_deg)
      << Fmt(" (%.3f px) RMS", rep.validation_rms_px) << " over " << rep.validation_count
      << " dots\n";
    t << "  normalised validation RMS:          " << Fmt("%.2f", rep.normalised_validation_rms)
      << "\n";
    if (have_truth) {
      t << "  plane normal error vs truth:        "
        << Fmt("%.4f deg RMS\n", rep.normal_rms_vs_truth_deg);
      t << "  alpha / beta / trans vs truth:      "
        << Fmt("%.4f deg / ", rep.alpha_rms_vs_truth_deg)
        << Fmt("%.4f deg / ", rep.beta_rms_vs_truth_deg)
        << Fmt("%.4f mm RMS\n", rep.trans_rms_vs_truth_mm);
    }
  } else {
    t << "  (skipped)\n";
  }
  t << "== Table II style: Hall sensor model ==\n";
  if (rep.have_hall) {
    t << "  model:                              " << rep.hall_model << "\n";
    t << "  test RMS alpha / beta / trans:      " << Fmt("%.4f deg / ", rep.test_rms[0])
      << Fmt("%.4f deg / ", rep.test_rms[1]) << Fmt("%.4f mm\n", rep.test_rms[2]);
    t << "  delta_t estimated:                  " << Fmt("%.4f ms", rep.delta_t_s * 1e3);
    if (have_truth)
      t << Fmt(" (truth %.4f ms", rep.delta_t_truth_s * 1e3)
        << Fmt(", error %.4f ms)", (rep.delta_t_s - rep.delta_t_truth_s) * 1e3);
    t << "\n";
    if (rep.have_hall_vs_truth)
      t << "  Hall prediction vs true pose:       " << Fmt("%.4f deg / ", rep.hall_rms_vs_truth[0])
        << Fmt("%.4f deg / ", rep.hall_rms_vs_truth[1])
        << Fmt("%.4f mm RMS\n", rep.hall_rms_vs_truth[2]);
  } else {
    t << "  (skipped)\n";
  }
  t << HallDroppedLine(dir);
  for (const auto& s : rep.skipped) t << "SKIPPED: " << s << "\n";
  rep.text = t.str();

  std::ostringstream h;
  h << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>msmcal calibration report</title>"
       "<style>body{font-family:sans-serif;max-width:1200px;margin:auto}pre{background:#f4f4f4;"
       "padding:8px}svg{margin:6px;border:1px solid #ddd}</style></head><body>";
  h << "<h1>msmcal calibration report</h1><p>Session folder: " << Escape(dir.string()) << "</p>";
  h << "<h2>Figures</h2><pre>" << Escape(rep.text) << "</pre>";
  h << "<h2>Plots</h2><div>";
  for (const auto& p : plots) h << p;
  h << "</div><h2>Session log</h2><pre>";
  for (const auto& n : session_notes) h << Escape(n) << "\n";
  h << "</pre></body></html>\n";
  rep.html = h.str();
  return rep;
}

}  // namespace msmcal::orchestrator

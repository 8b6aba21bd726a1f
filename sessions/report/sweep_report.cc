#include "sessions/report/sweep_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <sstream>

#include "common/text_io.h"
#include "sessions/report/build_info.h"
#include "sessions/sweep/sweep_state.h"

namespace msmcal::report {

namespace fs = std::filesystem;

namespace {

std::string Fmt(const char* format, double v) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

struct PointFigures {
  bool ok = false;
  std::string error;
  Level level = Level::kPass;
  SessionReport report;
};

}  // namespace

SweepReport BuildSweepReport(const fs::path& dir, const sweep::SweepPlan& plan,
                             const std::vector<sweep::SweepPoint>& points, const TruthSource& truth,
                             bool write_point_reports, const ReportOptions& point_options) {
  SweepReport rep;
  rep.points = static_cast<int>(points.size());
  const sweep::SweepState state = sweep::ReadSweepState(dir / "sweep_state.json");
  std::vector<PointFigures> figures(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const fs::path folder = dir / points[i].name;
    const auto st = state.points.find(points[i].name);
    if (st != state.points.end() && st->second.status == sweep::PointStatus::kDone) ++rep.done;
    if (!fs::exists(folder / "results")) {
      figures[i].error = "no results/ (point not run or not finished)";
      continue;
    }
    try {
      figures[i].report = write_point_reports ? WriteSessionReport(folder, point_options, truth)
                                              : BuildSessionReport(folder, point_options, truth);
      figures[i].ok = true;
      figures[i].level = Overall(figures[i].report.verdict);
      ++rep.reported;
    } catch (const std::exception& e) {
      figures[i].error = e.what();
    }
  }

  // Verdict: every point done, then each point's own verdict.
  VerdictLine all;
  all.name = "points done";
  all.figure = std::to_string(rep.done) + " of " + std::to_string(rep.points);
  all.rule = "pass when every point is done (sweep_state.json), fail otherwise";
  all.level = rep.done == rep.points ? Level::kPass : Level::kFail;
  rep.verdict.push_back(all);
  for (size_t i = 0; i < points.size(); ++i) {
    VerdictLine v;
    v.name = "point " + points[i].Label();
    if (figures[i].ok) {
      v.level = figures[i].level;
      int counts[3] = {0, 0, 0};
      for (const auto& l : figures[i].report.verdict) ++counts[static_cast<int>(l.level)];
      v.figure = std::to_string(counts[0]) + " pass, " + std::to_string(counts[1]) + " warn, " +
                 std::to_string(counts[2]) + " fail";
    } else {
      v.level = Level::kFail;
      v.figure = figures[i].error;
    }
    v.rule = "the worst line of the point's own verdict (its report)";
    rep.verdict.push_back(v);
  }

  // Table of points.
  Table t;
  t.id = "table-points";
  t.header = {"point"};
  for (const auto& a : plan.axes) t.header.push_back(sweep::ShortAxisName(a.path));
  t.header.insert(
      t.header.end(),
      {"repeat", "status", "verdict", "validation (deg RMS)", "normal vs truth (deg RMS)",
       "Hall model", "Hall alpha / beta (deg RMS)", "Hall trans (mm RMS)", "delta_t (ms)"});
  for (size_t i = 0; i < points.size(); ++i) {
    std::vector<std::string> row = {points[i].name};
    for (const auto& [path, value] : points[i].values) row.push_back(value);
    const auto st = state.points.find(points[i].name);
    row.push_back(std::to_string(points[i].repeat));
    row.push_back(st == state.points.end() ? "pending" : sweep::ToString(st->second.status));
    const PointFigures& f = figures[i];
    const SessionReport& r = f.report;
    row.push_back(f.ok ? ToString(f.level) : "-");
    row.push_back(f.ok && r.have_planes ? Fmt("%.4f", r.validation_rms_deg) : "-");
    row.push_back(f.ok && r.have_planes && truth ? Fmt("%.4f", r.normal_rms_vs_truth_deg) : "-");
    row.push_back(f.ok && r.have_hall ? r.hall_model : "-");
    row.push_back(f.ok && r.have_hall
                      ? Fmt("%.4f", r.test_rms[0]) + " / " + Fmt("%.4f", r.test_rms[1])
                      : "-");
    row.push_back(f.ok && r.have_hall ? Fmt("%.4f", r.test_rms[2]) : "-");
    row.push_back(f.ok && r.have_hall
                      ? (r.delta_t_identified ? Fmt("%.3f", r.delta_t_s * 1e3) : std::string("n/i"))
                      : "-");
    t.rows.push_back(row);
    t.row_links.push_back(
        fs::exists(dir / points[i].name / "report.html") ? points[i].name + "/report.html" : "");
  }
  t.caption = "Each point's name links its own report.";

  // Plots: each figure against each swept setting (numbers; other values by their rank).
  struct Metric {
    const char* id;
    const char* label;
    std::function<double(const SessionReport&)> value;
  };
  const std::vector<Metric> metrics = {
      {"normal", "plane normal error vs truth (deg RMS)",
       [&](const SessionReport& r) {
         return r.have_planes && truth ? r.normal_rms_vs_truth_deg : NAN;
       }},
      {"validation", "validation error (deg RMS)",
       [](const SessionReport& r) { return r.have_planes ? r.validation_rms_deg : NAN; }},
      {"hall", "Hall test RMS alpha (deg)",
       [](const SessionReport& r) { return r.have_hall ? r.test_rms[0] : NAN; }},
      {"delta-t", "delta_t (ms, identified points only)",
       [](const SessionReport& r) {
         return r.have_hall && r.delta_t_identified ? r.delta_t_s * 1e3 : NAN;
       }}};
  std::vector<std::string> not_plotted;  // metrics no point has a figure of
  for (size_t a = 0; a < plan.axes.size(); ++a) {
    std::map<std::string, double> rank;
    bool numeric = true;
    for (const auto& v : plan.axes[a].values) {
      char* end = nullptr;
      std::strtod(v.c_str(), &end);
      numeric = numeric && end && *end == '\0' && !v.empty();
      rank.emplace(v, static_cast<double>(rank.size()));
    }
    const std::string axis = sweep::ShortAxisName(plan.axes[a].path);
    for (const auto& m : metrics) {
      Chart c;
      c.id = "plot-sweep-" + std::string(m.id) + "-" + std::to_string(a);
      c.title = std::string(m.label) + " against " + axis;
      c.x_label = axis + (numeric ? "" : " (value index)");
      c.y_label = m.label;
      ChartSeries s;
      s.name = "points";
      s.colour = "#1f77b4";
      for (size_t i = 0; i < points.size(); ++i) {
        if (!figures[i].ok || a >= points[i].values.size()) continue;
        const std::string& v = points[i].values[a].second;
        s.x.push_back(numeric ? std::strtod(v.c_str(), nullptr) : rank[v]);
        s.y.push_back(m.value(figures[i].report));
      }
      if (std::none_of(s.y.begin(), s.y.end(), [](double y) { return std::isfinite(y); })) {
        // Nothing to draw (no point has this figure: no truth, no Hall model, delta_t not
        // identified): said in a line instead of an empty plot.
        not_plotted.push_back(std::string(m.label) + " against " + axis);
        continue;
      }
      c.series = {s};
      c.caption = "One dot per point (repeats included).";
      rep.charts.push_back(c);
    }
  }

  std::ostringstream txt;
  txt << "== Sweep verdict: " << ToString(Overall(rep.verdict)) << " ==\n";
  for (const auto& v : rep.verdict)
    txt << "  [" << ToString(v.level) << "] " << v.name << ": " << v.figure << "\n";
  rep.text = txt.str();

  std::ostringstream h;
  h << "<h1>msmcal sweep report</h1><p class=\"sub\">" << HtmlEscape(dir.string()) << " &middot; "
    << rep.points << " points" << (plan.note.empty() ? "" : " &middot; " + HtmlEscape(plan.note))
    << " &middot; msmcal " << MsmcalVersion() << " (" << GitCommit() << ")</p>\n";
  h << RenderVerdict(rep.verdict);
  h << "<h2>Points</h2>" << RenderTable(t);
  h << "<h2>Figures against the swept settings</h2><div class=\"plots\">";
  for (const auto& c : rep.charts) h << RenderChartPlace(c);
  h << "</div>\n";
  if (!not_plotted.empty()) {
    h << "<p class=\"sub\" id=\"not-plotted\">Not plotted, no point has a figure of it: ";
    for (size_t i = 0; i < not_plotted.size(); ++i)
      h << (i ? "; " : "") << HtmlEscape(not_plotted[i]);
    h << ".</p>\n";
  }
  h << "<p class=\"sub\">Plots: " << PlottingLibraryDescription() << ".</p>";
  rep.html = RenderPage("msmcal sweep report: " + dir.filename().string(), h.str(), rep.charts);
  return rep;
}

SweepReport WriteSweepReport(const fs::path& dir, const sweep::SweepPlan& plan,
                             const std::vector<sweep::SweepPoint>& points, const TruthSource& truth,
                             bool write_point_reports, const ReportOptions& point_options) {
  SweepReport r = BuildSweepReport(dir, plan, points, truth, write_point_reports, point_options);
  common::WriteFileAtomically(dir / "report.html", r.html);
  return r;
}

}  // namespace msmcal::report

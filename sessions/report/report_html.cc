#include "sessions/report/report_html.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

namespace msmcal::report {

// Generated at build time from /usr/share/javascript/chart.js/chart.min.js and its Debian
// copyright file (cmake/embed_text_file.cmake).
namespace embedded {
extern const char* const kChartJs;
extern const char* const kChartJs_licence;
extern const char* const kChartJs_version;
}  // namespace embedded

namespace {

// Draws every chart of the page's JSON with Chart.js; adds drag-to-zoom (x and y) and
// double-click to reset, and tooltips with 4 significant digits and the axis units.
constexpr const char* kBootstrap = R"js(
(function () {
  'use strict';
  const specs = JSON.parse(document.getElementById('msmcal-charts').textContent);
  const fmt = (v) => (v === null || v === undefined) ? '-' : Number(Number(v).toPrecision(4)).toString();
  const unit = (label) => { const m = /\(([^)]*)\)\s*$/.exec(label || ''); return m ? ' ' + m[1] : ''; };
  const tint = (hex) => hex + '33';
  window.msmcalCharts = {};
  for (const s of specs) {
    const canvas = document.getElementById(s.id);
    if (!canvas) { continue; }
    const bar = s.categories.length > 0;
    const datasets = [];
    for (const ser of s.series) {
      const pts = (ys) => bar ? ys : ser.x.map((x, i) => ({x: x, y: ys[i]}));
      if (ser.y_lo.length) {
        datasets.push({label: ser.name + ' -sigma', band: true, data: pts(ser.y_lo), showLine: true,
                       pointRadius: 0, borderWidth: 0, borderColor: 'transparent', fill: false});
        datasets.push({label: ser.name + ' +sigma', band: true, data: pts(ser.y_hi), showLine: true,
                       pointRadius: 0, borderWidth: 0, borderColor: 'transparent',
                       backgroundColor: tint(ser.colour), fill: '-1'});
      }
      const d = {label: ser.name, data: pts(ser.y), borderColor: ser.colour,
                 backgroundColor: ser.colour, spanGaps: false};
      if (ser.style === 'bar') { d.type = 'bar'; }
      else if (ser.style === 'points') { d.showLine = false; d.pointRadius = 2.5; }
      else { d.showLine = true; d.pointRadius = 0; d.borderWidth = 1.5;
             if (ser.style === 'step') { d.stepped = 'middle'; } }
      datasets.push(d);
    }
    const scales = {
      x: {type: bar ? 'category' : (s.x_log ? 'logarithmic' : 'linear'),
          title: {display: true, text: s.x_label}},
      y: {type: s.y_log ? 'logarithmic' : 'linear', reverse: s.y_reversed,
          title: {display: true, text: s.y_label}}
    };
    const chart = new Chart(canvas, {
      type: bar ? 'bar' : 'scatter',
      data: bar ? {labels: s.categories, datasets: datasets} : {datasets: datasets},
      options: {
        animation: false, responsive: true, maintainAspectRatio: false,
        interaction: {mode: 'nearest', intersect: false},
        scales: scales,
        plugins: {
          title: {display: true, text: s.title},
          legend: {labels: {filter: (item, data) => !data.datasets[item.datasetIndex].band}},
          tooltip: {filter: (item) => !item.dataset.band, callbacks: {label: (ctx) => bar
            ? ctx.dataset.label + ': ' + fmt(ctx.parsed.y) + unit(s.y_label)
            : ctx.dataset.label + ': ' + fmt(ctx.parsed.x) + unit(s.x_label) + ', ' +
              fmt(ctx.parsed.y) + unit(s.y_label)}}
        }
      }
    });
    window.msmcalCharts[s.id] = chart;
    // Drag a rectangle to zoom; double-click to reset.
    const box = document.createElement('div');
    box.className = 'zoombox';
    canvas.parentNode.appendChild(box);
    let start = null;
    const pos = (e) => { const r = canvas.getBoundingClientRect(); return {x: e.clientX - r.left, y: e.clientY - r.top}; };
    canvas.addEventListener('mousedown', (e) => { start = pos(e); });
    canvas.addEventListener('mousemove', (e) => {
      if (!start) { return; }
      const p = pos(e);
      Object.assign(box.style, {display: 'block', left: Math.min(p.x, start.x) + 'px', top: Math.min(p.y, start.y) + 'px',
                                width: Math.abs(p.x - start.x) + 'px', height: Math.abs(p.y - start.y) + 'px'});
    });
    window.addEventListener('mouseup', (e) => {
      if (!start) { return; }
      const p = pos(e), a = start;
      start = null;
      box.style.display = 'none';
      if (Math.abs(p.x - a.x) < 5 || Math.abs(p.y - a.y) < 5) { return; }
      const xs = chart.scales.x, ys = chart.scales.y;
      if (!bar) {
        const x0 = xs.getValueForPixel(a.x), x1 = xs.getValueForPixel(p.x);
        chart.options.scales.x.min = Math.min(x0, x1); chart.options.scales.x.max = Math.max(x0, x1);
      }
      const y0 = ys.getValueForPixel(a.y), y1 = ys.getValueForPixel(p.y);
      chart.options.scales.y.min = Math.min(y0, y1); chart.options.scales.y.max = Math.max(y0, y1);
      chart.update('none');
    });
    canvas.addEventListener('dblclick', () => {
      for (const k of ['x', 'y']) { delete chart.options.scales[k].min; delete chart.options.scales[k].max; }
      chart.update('none');
    });
  }
})();
)js";

constexpr const char* kStyle = R"css(
body{font-family:system-ui,sans-serif;max-width:1280px;margin:1em auto;padding:0 1em;color:#222}
h1{margin-bottom:0.2em} .sub{color:#666;margin-top:0}
#verdict{border:2px solid #999;border-radius:8px;padding:0.5em 1em;margin:1em 0}
#verdict.pass{border-color:#2ca02c;background:#f2fbf2} #verdict.warn{border-color:#e6a100;background:#fffaf0}
#verdict.fail{border-color:#d62728;background:#fff4f4}
#verdict ul{list-style:none;padding:0} #verdict li{margin:0.35em 0}
.badge{display:inline-block;width:3.6em;text-align:center;border-radius:4px;color:#fff;font-weight:bold;margin-right:0.5em}
li.pass .badge,.badge.pass{background:#2ca02c} li.warn .badge,.badge.warn{background:#e6a100} li.fail .badge,.badge.fail{background:#d62728}
.rule{color:#666;font-size:0.85em;display:block;margin-left:4.4em}
table{border-collapse:collapse;margin:0.5em 0 1em} th,td{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f0f0f0} td:first-child,th:first-child{text-align:left} caption{caption-side:bottom;color:#666;font-size:0.85em;text-align:left}
.plots{display:flex;flex-wrap:wrap;gap:12px}
figure{margin:0;width:600px} .plot{position:relative;height:380px;border:1px solid #ddd}
figcaption{color:#555;font-size:0.85em}
.zoombox{position:absolute;display:none;border:1px dashed #333;background:rgba(100,100,255,0.1);pointer-events:none}
pre{background:#f4f4f4;padding:8px;overflow:auto;max-height:30em} code{font-size:0.9em}
)css";

const char* StyleName(ChartSeries::Style s) {
  switch (s) {
    case ChartSeries::Style::kPoints:
      return "points";
    case ChartSeries::Style::kLine:
      return "line";
    case ChartSeries::Style::kStep:
      return "step";
    case ChartSeries::Style::kBar:
      return "bar";
  }
  return "points";
}

nlohmann::json Numbers(const std::vector<double>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (double x : v) a.push_back(std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr));
  return a;
}

// JSON inside <script>: no "</" (it could close the element).
std::string ScriptSafe(std::string s) {
  for (size_t p = s.find("</"); p != std::string::npos; p = s.find("</", p + 3))
    s.replace(p, 2, "<\\/");
  return s;
}

}  // namespace

std::string HtmlEscape(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '&':
        o += "&amp;";
        break;
      case '"':
        o += "&quot;";
        break;
      case '\'':
        o += "&#39;";
        break;
      default:
        o += c;
    }
  }
  return o;
}

std::string RenderTable(const Table& t) {
  std::ostringstream o;
  if (!t.title.empty()) o << "<h3>" << HtmlEscape(t.title) << "</h3>";
  o << "<table id=\"" << HtmlEscape(t.id) << "\">";
  if (!t.caption.empty()) o << "<caption>" << HtmlEscape(t.caption) << "</caption>";
  o << "<thead><tr>";
  for (const auto& h : t.header) o << "<th>" << HtmlEscape(h) << "</th>";
  o << "</tr></thead><tbody>";
  for (size_t i = 0; i < t.rows.size(); ++i) {
    o << "<tr>";
    for (size_t k = 0; k < t.rows[i].size(); ++k) {
      const std::string cell = HtmlEscape(t.rows[i][k]);
      if (k == 0 && i < t.row_links.size() && !t.row_links[i].empty())
        o << "<td><a href=\"" << HtmlEscape(t.row_links[i]) << "\">" << cell << "</a></td>";
      else
        o << "<td>" << cell << "</td>";
    }
    o << "</tr>";
  }
  o << "</tbody></table>\n";
  return o.str();
}

std::string RenderVerdict(const std::vector<VerdictLine>& lines) {
  const Level overall = Overall(lines);
  std::ostringstream o;
  o << "<section id=\"verdict\" class=\"" << ToString(overall)
    << "\"><h2>Verdict: <span class=\"badge " << ToString(overall) << "\">" << ToString(overall)
    << "</span></h2>";
  if (lines.empty()) o << "<p>No figure could be judged (see Skipped below).</p>";
  o << "<ul>";
  for (const auto& l : lines)
    o << "<li class=\"" << ToString(l.level) << "\"><span class=\"badge\">" << ToString(l.level)
      << "</span><b>" << HtmlEscape(l.name) << "</b>: " << HtmlEscape(l.figure)
      << "<span class=\"rule\">rule: " << HtmlEscape(l.rule) << "</span></li>";
  o << "</ul></section>\n";
  return o.str();
}

std::string RenderChartPlace(const Chart& c) {
  std::ostringstream o;
  o << "<figure><div class=\"plot\"><canvas id=\"" << HtmlEscape(c.id)
    << "\" class=\"msmcal-plot\"></canvas></div><figcaption>" << HtmlEscape(c.caption)
    << (c.caption.empty() ? "" : " ")
    << "Drag to zoom, double-click to reset.</figcaption></figure>";
  return o.str();
}

std::string ChartsJson(const std::vector<Chart>& charts) {
  nlohmann::json all = nlohmann::json::array();
  for (const auto& c : charts) {
    nlohmann::json j = {{"id", c.id},
                        {"title", c.title},
                        {"x_label", c.x_label},
                        {"y_label", c.y_label},
                        {"categories", c.categories},
                        {"y_reversed", c.y_reversed},
                        {"x_log", c.x_log},
                        {"y_log", c.y_log}};
    nlohmann::json series = nlohmann::json::array();
    for (const auto& s : c.series)
      series.push_back({{"name", s.name},
                        {"x", Numbers(s.x)},
                        {"y", Numbers(s.y)},
                        {"y_lo", Numbers(s.y_lo)},
                        {"y_hi", Numbers(s.y_hi)},
                        {"style", StyleName(s.style)},
                        {"colour", s.colour}});
    j["series"] = series;
    all.push_back(j);
  }
  return all.dump();
}

std::string RenderPage(const std::string& title, const std::string& body_html,
                       const std::vector<Chart>& charts) {
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>"
    << HtmlEscape(title) << "</title><style>" << kStyle << "</style>\n";
  // The library's licence (MIT, from Debian's copyright file), kept with the copy we embed.
  std::string licence = embedded::kChartJs_licence;
  for (size_t p = licence.find("--"); p != std::string::npos; p = licence.find("--", p))
    licence.replace(p, 2, "- ");
  h << "<!-- Embedded plotting library: " << PlottingLibraryDescription() << ".\n"
    << licence << "\n-->\n";
  h << "<script>" << embedded::kChartJs << "</script>\n</head><body>\n";
  h << body_html;
  h << "<script type=\"application/json\" id=\"msmcal-charts\">" << ScriptSafe(ChartsJson(charts))
    << "</script>\n<script>" << kBootstrap << "</script>\n</body></html>\n";
  return h.str();
}

std::string PlottingLibraryDescription() {
  return std::string("Chart.js ") + embedded::kChartJs_version +
         " (Debian package libjs-chart.js, MIT licence), embedded in this file";
}

}  // namespace msmcal::report

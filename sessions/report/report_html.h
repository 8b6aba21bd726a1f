#pragma once
// The report's HTML: one self-contained, offline page (no network when it is opened). Plots are
// Chart.js charts (Debian's libjs-chart.js, embedded into the binary at build time: the page
// carries the library and its licence), drawn from JSON chart specifications in the page:
// interactive (values on hover, drag a rectangle to zoom, double-click to reset), ticks and
// tooltips with units from the axis labels. Tables are HTML tables; the verdict is the first
// element of the page, id="verdict".

#include <string>
#include <vector>

#include "sessions/report/verdict.h"

namespace msmcal::report {

// One data series of a chart. Non-finite values are gaps (JSON null).
struct ChartSeries {
  std::string name;
  std::vector<double> x, y;
  // Optional band around y (same size as y): drawn filled between y_lo and y_hi (+-sigma).
  std::vector<double> y_lo, y_hi;
  enum class Style { kPoints, kLine, kStep, kBar };
  Style style = Style::kPoints;
  std::string colour = "#1f77b4";  // "#rrggbb"
};

struct Chart {
  std::string id;                       // DOM id of the canvas: "plot-<name>", unique in a page
  std::string title, x_label, y_label;  // axis labels carry the units: "alpha (deg)"
  std::vector<ChartSeries> series;
  // Bar charts: category labels on x (each series' y has one value per category; x ignored).
  std::vector<std::string> categories;
  bool y_reversed = false;  // image rows grow downwards
  bool x_log = false, y_log = false;
  std::string caption;  // what the plot shows and how to read it
};

struct Table {
  std::string id, title;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;  // cells as text (escaped when rendered)
  // Optional, one per row: the row's first cell links to this relative URL ("" for none).
  std::vector<std::string> row_links;
  std::string caption;
};

std::string HtmlEscape(const std::string& text);
std::string RenderTable(const Table& table);
// <section id="verdict">: the overall level, then one <li class="pass|warn|fail"> per line with
// its figure and rule.
std::string RenderVerdict(const std::vector<VerdictLine>& lines);
// The chart's place in the page (<figure> with its canvas and caption).
std::string RenderChartPlace(const Chart& chart);
// The charts' specification as the page's JSON (exposed for tests).
std::string ChartsJson(const std::vector<Chart>& charts);
// A whole page: `body_html` (which holds RenderChartPlace of each chart) plus the embedded
// plotting library, its licence, the charts' JSON and the script that draws them.
std::string RenderPage(const std::string& title, const std::string& body_html,
                       const std::vector<Chart>& charts);

// "Chart.js 3.9.1 (Debian libjs-chart.js, MIT licence), embedded" for the report's footer.
std::string PlottingLibraryDescription();

}  // namespace msmcal::report

#include "sessions/report/report_html.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

namespace msmcal::report {
namespace {

TEST(ReportHtml, PageEmbedsTheLibraryAndNeedsNoNetwork) {
  Chart c;
  c.id = "plot-x";
  c.title = "t";
  ChartSeries s;
  s.x = {0, 1};
  s.y = {2, 3};
  c.series = {s};
  const std::string page = RenderPage("title <x>", RenderChartPlace(c), {c});
  EXPECT_NE(page.find("<title>title &lt;x&gt;</title>"), std::string::npos);
  EXPECT_NE(page.find("Chart.js v"), std::string::npos);  // the library's own header
  EXPECT_NE(page.find("Permission is hereby granted"), std::string::npos);  // its licence
  EXPECT_NE(page.find("<canvas id=\"plot-x\""), std::string::npos);
  // Offline: nothing is loaded from elsewhere.
  EXPECT_EQ(page.find("<script src"), std::string::npos);
  EXPECT_EQ(page.find("<link "), std::string::npos);
  EXPECT_NE(PlottingLibraryDescription().find("Chart.js 3."), std::string::npos);
}

TEST(ReportHtml, ChartsJsonCarriesSeriesBandsAndGaps) {
  Chart c;
  c.id = "plot-a";
  c.x_label = "t (s)";
  ChartSeries s;
  s.name = "alpha";
  s.x = {0, 1, 2};
  s.y = {1, NAN, 3};
  s.y_lo = {0.5, 1, 2.5};
  s.y_hi = {1.5, 2, 3.5};
  s.style = ChartSeries::Style::kStep;
  c.series = {s};
  const auto j = nlohmann::json::parse(ChartsJson({c}));
  ASSERT_EQ(j.size(), 1u);
  EXPECT_EQ(j[0]["id"], "plot-a");
  EXPECT_EQ(j[0]["x_label"], "t (s)");
  EXPECT_EQ(j[0]["series"][0]["style"], "step");
  EXPECT_TRUE(j[0]["series"][0]["y"][1].is_null());  // a gap, not NaN text
  EXPECT_EQ(j[0]["series"][0]["y_hi"][2], 3.5);
}

TEST(ReportHtml, ScriptDataCannotCloseItsElement) {
  Chart c;
  c.id = "plot-a";
  c.title = "</script><script>alert(1)</script>";
  const std::string page = RenderPage("t", "", {c});
  EXPECT_EQ(page.find("</script><script>alert"), std::string::npos);
}

TEST(ReportHtml, TablesAndVerdictAreEscapedAndLinked) {
  Table t;
  t.id = "table-x";
  t.header = {"a", "b"};
  t.rows = {{"p1", "<1>"}, {"p2", "2"}};
  t.row_links = {"p1/report.html", ""};
  const std::string h = RenderTable(t);
  EXPECT_NE(h.find("<table id=\"table-x\">"), std::string::npos);
  EXPECT_NE(h.find("<td>&lt;1&gt;</td>"), std::string::npos);
  EXPECT_NE(h.find("<a href=\"p1/report.html\">p1</a>"), std::string::npos);
  EXPECT_NE(h.find("<td>p2</td>"), std::string::npos);

  VerdictLine w{Level::kWarn, "n", "f & g", "r"};
  VerdictLine p{Level::kPass, "m", "ok", "r2"};
  const std::string v = RenderVerdict({p, w});
  EXPECT_EQ(v.find("<section id=\"verdict\" class=\"warn\">"), 0u) << v;
  EXPECT_NE(v.find("<li class=\"pass\">"), std::string::npos);
  EXPECT_NE(v.find("f &amp; g"), std::string::npos);
  EXPECT_NE(v.find("rule: r2"), std::string::npos);
}

}  // namespace
}  // namespace msmcal::report

#include "sessions/report/session_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "sessions/report/build_info.h"
#include "sessions/results/results_files.h"
#include "tests/testing/test_files.h"

namespace msmcal::report {
namespace {

namespace fs = std::filesystem;

const VerdictLine* Find(const SessionReport& r, const std::string& prefix) {
  for (const auto& v : r.verdict)
    if (v.name.rfind(prefix, 0) == 0) return &v;
  return nullptr;
}

const Chart* FindChart(const SessionReport& r, const std::string& id) {
  for (const auto& c : r.charts)
    if (c.id == id) return &c;
  return nullptr;
}

// A results/ folder as `msmcal solve` writes it (no session.yaml, no Hall, no truth): 12 planes
// and 40 held-out dots whose normalised errors are an honest chi2(2) sample.
fs::path SolvedFolder(const fs::path& dir, double error_scale) {
  std::vector<dataset::MirrorPlaneRow> planes;
  for (int j = 0; j < 12; ++j) {
    dataset::MirrorPlaneRow p;
    p.j = j;
    p.t_s = 0.01 * j;
    p.plane_in_world.n = Eigen::Vector3d(0, 0, 1);
    p.alpha_deg = std::sin(j), p.beta_deg = std::cos(j), p.trans_mm = 0.01 * j;
    p.sigma_alpha_deg = p.sigma_beta_deg = 0.001, p.sigma_trans_mm = 0.002;
    planes.push_back(p);
  }
  results::WriteMirrorPlanesCsv(dir / "results" / "mirror_planes.csv", planes);
  std::vector<results::ValidationDetailRow> detail;
  for (int i = 0; i < 40; ++i) {
    results::ValidationDetailRow d;
    d.beam = 2;
    d.j = i % 12;
    d.predicted_sigma_px = 0.2;
    // NEES 2 ne^2 = chi2(2) quantile at (i + 0.5) / 40: -2 ln(1 - p).
    d.normalised_error = error_scale * std::sqrt(-std::log1p(-(i + 0.5) / 40));
    d.err_px = d.normalised_error * 0.2 * std::sqrt(2.0);
    d.baseline_err_px = 3 * d.err_px;
    detail.push_back(d);
  }
  results::WriteValidationDetailCsv(dir / "results" / "validation_detail.csv", detail);
  results::MirrorPosesSummary s;
  s.planes_scan = 12;
  s.validation_rms_deg = 0.01;
  s.validation_count = 40;
  s.variance_factors = {{"corners", 1.1, 100}, {"sliding_dots", 0.9, 50}};
  s.dropped_frames = {{"step1/0003.png", "too few dots"},
                      {"step1/0004.png", "too few dots"},
                      {"step2/0001.png", "no board"}};
  results::WriteMirrorPosesSummary(dir / "results" / "summary.json", s);
  return dir;
}

TEST(SessionReport, SaysWhatIsMissingInsteadOfInventingFigures) {
  testing::TempDir tmp;
  const SessionReport r = BuildSessionReport(tmp.path(), {}, /*truth=*/{});
  EXPECT_FALSE(r.have_planes);
  EXPECT_FALSE(r.have_hall);
  EXPECT_TRUE(r.verdict.empty());  // nothing judged on missing figures
  EXPECT_NE(r.text.find("SKIPPED: Table I figures"), std::string::npos) << r.text;
  EXPECT_NE(r.html.find("No figure could be judged"), std::string::npos);
  EXPECT_NE(r.html.find("id=\"skipped\""), std::string::npos);
}

TEST(SessionReport, HonestSolveOpensOnAPassingVerdictWithTablesAndPlots) {
  testing::TempDir tmp;
  SolvedFolder(tmp.path(), 1.0);
  const SessionReport r = BuildSessionReport(tmp.path(), {}, {});
  ASSERT_TRUE(r.have_planes);
  EXPECT_EQ(r.planes, 12);
  const VerdictLine* nees = Find(r, "sigma honest");
  ASSERT_NE(nees, nullptr);
  EXPECT_EQ(nees->level, Level::kPass) << nees->figure;
  ASSERT_NE(Find(r, "held-out dots inside"), nullptr);
  EXPECT_EQ(Find(r, "held-out dots inside")->level, Level::kPass);
  const VerdictLine* dropped = Find(r, "frames dropped");
  ASSERT_NE(dropped, nullptr);
  EXPECT_NE(dropped->figure.find("main reason (2): too few dots"), std::string::npos)
      << dropped->figure;
  // No session.yaml: the planes against triggers are not judged (never guessed).
  EXPECT_EQ(Find(r, "scan planes solved"), nullptr);

  // The verdict comes first in the page, then the tables and the plots.
  const size_t verdict = r.html.find("<section id=\"verdict\"");
  const size_t table1 = r.html.find("<table id=\"table-one\">");
  ASSERT_NE(verdict, std::string::npos);
  ASSERT_NE(table1, std::string::npos);
  EXPECT_LT(verdict, table1);
  EXPECT_LT(r.html.find("<h1>"), verdict);
  EXPECT_NE(r.html.find("<table id=\"table-dropped-frames\">"), std::string::npos);
  for (const char* id : {"plot-scan-pattern", "plot-pose-alpha", "plot-pose-beta",
                         "plot-pose-trans", "plot-residual-families", "plot-normalised-errors",
                         "plot-validation-sigma", "plot-validation-residuals"}) {
    const Chart* c = FindChart(r, id);
    ASSERT_NE(c, nullptr) << id;
    ASSERT_FALSE(c->series.empty()) << id;
    EXPECT_NE(r.html.find(std::string("<canvas id=\"") + id + "\""), std::string::npos) << id;
  }
  // The +-sigma band of alpha is the solver's sigma.
  const ChartSeries& a = FindChart(r, "plot-pose-alpha")->series[0];
  ASSERT_EQ(a.y_hi.size(), 12u);
  EXPECT_NEAR(a.y_hi[0] - a.y[0], 0.001, 1e-12);
  // The histogram counts every held-out dot; the expected curve integrates to about the same.
  const Chart* h = FindChart(r, "plot-normalised-errors");
  double n = 0;
  for (double y : h->series[0].y) n += y;
  EXPECT_EQ(n, 40);
  // Provenance: this binary's commit, in the page and in summary.json.
  EXPECT_NE(r.html.find(GitCommit()), std::string::npos);
  const auto summary =
      nlohmann::json::parse(testing::Slurp(tmp.path() / "results" / "summary.json"));
  EXPECT_EQ(summary["provenance"]["git_commit"], GitCommit());
  EXPECT_TRUE(summary.contains("mirror_poses"));
  EXPECT_NE(r.text.find("== Verdict: "), std::string::npos);
  EXPECT_NE(r.text.find("[pass] sigma honest"), std::string::npos) << r.text;
}

TEST(SessionReport, MargCostsBeforeAndAfterAsATableAndAPlot) {
  testing::TempDir tmp;
  testing::Spit(tmp.path() / "results" / "marg_calibration.yaml",
                "format: msmcal-marg-calibration/1\nvalidation:\n  mean_cost_raw: 0.022\n"
                "  mean_cost_compensated: 0.0012\n  mean_cost_aligned_compensated: 1.3e-05\n");
  const SessionReport r = BuildSessionReport(tmp.path(), {}, {});
  const Chart* m = FindChart(r, "plot-marg");
  ASSERT_NE(m, nullptr);
  ASSERT_EQ(m->series.size(), 1u);
  EXPECT_EQ(m->series[0].y, (std::vector<double>{0.022, 0.0012, 1.3e-5}));
  EXPECT_NE(r.html.find("<table id=\"table-marg\">"), std::string::npos);
  EXPECT_NE(r.html.find("<td>0.0012</td>"), std::string::npos);
}

TEST(SessionReport, OverConfidentSigmasFailTheVerdict) {
  testing::TempDir tmp;
  SolvedFolder(tmp.path(), 2.0);
  const SessionReport r = BuildSessionReport(tmp.path(), {}, {});
  ASSERT_NE(Find(r, "sigma honest"), nullptr);
  EXPECT_EQ(Find(r, "sigma honest")->level, Level::kFail);
  EXPECT_EQ(Overall(r.verdict), Level::kFail);
  EXPECT_NE(r.html.find("<section id=\"verdict\" class=\"fail\">"), std::string::npos);
}

TEST(SessionReport, WritesReportHtmlAndANamedErrorForABadFile) {
  testing::TempDir tmp;
  SolvedFolder(tmp.path(), 1.0);
  (void)WriteSessionReport(tmp.path(), {}, {});
  EXPECT_TRUE(fs::exists(tmp.path() / "report.html"));
  testing::Spit(tmp.path() / "results" / "mirror_planes.csv", "garbage\n");
  try {
    (void)BuildSessionReport(tmp.path(), {}, {});
    FAIL() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("mirror_planes.csv"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace msmcal::report

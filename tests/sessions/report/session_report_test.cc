#include "sessions/report/session_report.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

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

// Held-out dots on one beam whose errors e_i = b + n_i share the beam's error b (covariance
// sigma_b^2 I) besides their own n_i (sigma_n^2 I): the joint covariance of the stacked errors
// is sigma_n^2 I + sigma_b^2 (1 1^T kron I2), each dot's marginal one (sigma_b^2 + sigma_n^2) I.
struct HeldOutSample {
  std::vector<results::ValidationDetailRow> detail;
  std::vector<results::ValidationDotRow> dots;
};
HeldOutSample CorrelatedHeldOutDots(int n, double sigma_b, double sigma_n, const Eigen::Vector2d& b,
                                    uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double var = sigma_b * sigma_b + sigma_n * sigma_n;
  Eigen::MatrixXd c = Eigen::MatrixXd::Identity(2 * n, 2 * n) * sigma_n * sigma_n;
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k)
      c.block<2, 2>(2 * i, 2 * k) += Eigen::Matrix2d::Identity() * sigma_b * sigma_b;
  Eigen::VectorXd e(2 * n);
  HeldOutSample s;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d ei = b + sigma_n * Eigen::Vector2d(gauss(rng), gauss(rng));
    e.segment<2>(2 * i) = ei;
    results::ValidationDotRow d;
    d.beam = 2;
    d.j = i;
    d.predicted_px = Eigen::Vector2d(100 + 40 * i, 300 + 20 * (i % 7));
    d.observed_px = d.predicted_px + ei;
    d.cov_px2 = Eigen::Matrix2d::Identity() * var;
    s.dots.push_back(d);
    results::ValidationDetailRow r;
    r.beam = 2;
    r.j = i;
    r.err_px = ei.norm();
    r.baseline_err_px = 3 * r.err_px;
    r.predicted_sigma_px = std::sqrt(var);
    r.normalised_error = std::sqrt(ei.squaredNorm() / var / 2);
    s.detail.push_back(r);
  }
  const Eigen::VectorXd w =
      Eigen::MatrixXd(c.llt().matrixL()).triangularView<Eigen::Lower>().solve(e);
  for (int i = 0; i < n; ++i) s.dots[i].joint_whitened = w.segment<2>(2 * i);
  return s;
}

// A results/ folder as `msmcal solve` writes it (no session.yaml, no Hall, no truth): 12 planes
// and 40 held-out dots whose normalised errors are an honest chi2(2) sample (independent dots:
// their joint whitening is their own), fitted residuals of four families.
fs::path SolvedFolder(const fs::path& dir, double error_scale,
                      const HeldOutSample* held_out = nullptr) {
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
  HeldOutSample sample;
  if (held_out) sample = *held_out;
  for (int i = 0; !held_out && i < 40; ++i) {
    results::ValidationDetailRow d;
    d.beam = 2;
    d.j = i % 12;
    d.predicted_sigma_px = 0.2;
    // NEES 2 ne^2 = chi2(2) quantile at (i + 0.5) / 40: -2 ln(1 - p).
    d.normalised_error = error_scale * std::sqrt(-std::log1p(-(i + 0.5) / 40));
    d.err_px = d.normalised_error * 0.2 * std::sqrt(2.0);
    d.baseline_err_px = 3 * d.err_px;
    sample.detail.push_back(d);
    results::ValidationDotRow v;
    v.beam = d.beam;
    v.j = d.j;
    const Eigen::Vector2d dir_i(std::cos(2.4 * i), std::sin(2.4 * i));
    v.predicted_px = Eigen::Vector2d(200 + 50 * i, 1000 - 20 * i);
    v.observed_px = v.predicted_px + d.err_px * dir_i;
    v.cov_px2 = Eigen::Matrix2d::Identity() * 0.04;
    v.joint_whitened = std::sqrt(2.0) * d.normalised_error * dir_i;
    sample.dots.push_back(v);
  }
  results::WriteValidationDetailCsv(dir / "results" / "validation_detail.csv", sample.detail);
  results::WriteValidationDotsCsv(dir / "results" / "validation_dots.csv", sample.dots);
  // Fitted residuals: normal quantiles, shuffled between the two components.
  std::vector<solver::WhitenedResidual> residuals;
  for (int f : {solver::kCornersC1World, solver::kCornersC2World, solver::kSlidingDots,
                solver::kReflectedDots})
    for (int i = 0; i < 200; ++i) {
      // Inverse normal CDF of (i + 0.5) / 200 by bisection on erfc.
      auto quantile = [](double p) {
        double lo = -10, hi = 10;
        for (int it = 0; it < 100; ++it) {
          const double mid = (lo + hi) / 2;
          (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
        }
        return (lo + hi) / 2;
      };
      residuals.push_back(
          {f, i % 5, Eigen::Vector2d(i, 2 * i),
           Eigen::Vector2d(quantile((i + 0.5) / 200), quantile(((i * 77) % 200 + 0.5) / 200))});
    }
  results::WriteResidualsCsv(dir / "results" / "residuals.csv", residuals);
  results::MirrorPosesSummary s;
  s.planes_scan = 12;
  s.validation_rms_deg = 0.01;
  s.validation_count = static_cast<int>(sample.dots.size());
  s.variance_factors = {{"corners_c1_world", 1.1, 100}, {"sliding_dots", 0.9, 50}};
  s.dropped_frames = {{"step1/0003.png", "too few dots"},
                      {"step1/0004.png", "too few dots"},
                      {"step2/0001.png", "no board"}};
  s.beam_direction_sigma_deg = {0.0175, 0.0182, 0.0172};
  s.rms_sigma_normal_world_deg = 0.0309;
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
  // Table I says how uncertain the planes and beams are in {W} (summary.json), not only in {0}.
  EXPECT_NE(r.html.find("normals are uncertain by 0.0309 deg (RMS sigma) and the beam "
                        "directions by 0.0175 / 0.0182 / 0.0172 deg"),
            std::string::npos);
  for (const char* id :
       {"plot-scan-pattern", "plot-pose-alpha", "plot-pose-beta", "plot-pose-trans",
        "plot-residual-families", "plot-whitened-histogram", "plot-normalised-errors",
        "plot-validation-sigma", "plot-validation-residuals", "plot-validation-vectors"}) {
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

TEST(SessionReport, CorrelatedHeldOutDotsAreJudgedOnTheirJointWhitening) {
  // One beam error of 1.6 sigma_b (chi2(2) = 2.56: 28 % of honest solves have a larger one),
  // shared by 40 dots (correlation 0.9): every dot's marginal error is about 1.5 of its sigma,
  // so few are inside their marginal 1-sigma ellipse, although the covariances are honest.
  // Judged as 40 independent dots that failed.
  const double sigma_b = 0.18, sigma_n = 0.06;
  const HeldOutSample sample = CorrelatedHeldOutDots(
      40, sigma_b, sigma_n, Eigen::Vector2d(1.6 * sigma_b * 0.6, 1.6 * sigma_b * 0.8), 5);
  int inside_marginal = 0;
  for (const auto& d : sample.detail)
    inside_marginal += 2 * d.normalised_error * d.normalised_error <= 1;
  ASSERT_LE(inside_marginal, 6) << "the sample does not show the effect";
  std::vector<double> marginal;
  for (const auto& d : sample.detail) marginal.push_back(d.normalised_error);
  ASSERT_EQ(JudgeEllipseCoverage(marginal).level, Level::kFail);

  testing::TempDir tmp;
  SolvedFolder(tmp.path(), 1.0, &sample);
  const SessionReport r = BuildSessionReport(tmp.path(), {}, {});
  const VerdictLine* coverage = Find(r, "held-out dots inside");
  ASSERT_NE(coverage, nullptr);
  EXPECT_EQ(coverage->level, Level::kPass) << coverage->figure;
  EXPECT_NE(coverage->figure.find("whitened jointly"), std::string::npos) << coverage->figure;
  const VerdictLine* nees = Find(r, "sigma honest");
  ASSERT_NE(nees, nullptr);
  EXPECT_EQ(nees->level, Level::kPass) << nees->figure;
}

TEST(SessionReport, HeldOutResidualVectorsOnTheImageWithTheirScale) {
  testing::TempDir tmp;
  SolvedFolder(tmp.path(), 1.0);
  const SessionReport r = BuildSessionReport(tmp.path(), {}, {});
  const Chart* v = FindChart(r, "plot-validation-vectors");
  ASSERT_NE(v, nullptr);
  EXPECT_TRUE(v->y_reversed);  // image rows grow downwards
  ASSERT_GE(v->series.size(), 3u);
  const ChartSeries& vec = v->series[0];
  // One segment per dot (predicted, tip, gap); the tip is predicted + scale x error, and the
  // legend and title say the scale.
  const std::vector<results::ValidationDotRow> dots =
      results::ReadValidationDotsCsv(tmp.path() / "results" / "validation_dots.csv");
  ASSERT_EQ(vec.x.size(), 3 * dots.size());
  const double scale = (vec.x[1] - vec.x[0]) / (dots[0].observed_px - dots[0].predicted_px).x();
  EXPECT_GT(scale, 1);
  char text[32];
  std::snprintf(text, sizeof(text), "x%g", scale);
  EXPECT_NE(vec.name.find(text), std::string::npos) << vec.name << " / " << scale;
  EXPECT_NE(v->title.find(text), std::string::npos) << v->title;
  for (size_t i = 0; i < dots.size(); ++i) {
    EXPECT_DOUBLE_EQ(vec.x[3 * i], dots[i].predicted_px.x());
    EXPECT_NEAR(
        vec.y[3 * i + 1],
        dots[i].predicted_px.y() + scale * (dots[i].observed_px.y() - dots[i].predicted_px.y()),
        1e-9);
    EXPECT_TRUE(std::isnan(vec.x[3 * i + 2]));
  }
  // The 1-sigma ellipse of a dot with C = 0.04 I is a circle of radius scale x 0.2.
  const ChartSeries& ell = v->series[1];
  EXPECT_NEAR(std::hypot(ell.x[0] - dots[0].predicted_px.x(), ell.y[0] - dots[0].predicted_px.y()),
              scale * 0.2, 1e-9);
}

TEST(SessionReport, WhitenedResidualsByFamilyAgainstTheNormalDensity) {
  testing::TempDir tmp;
  SolvedFolder(tmp.path(), 1.0);
  const SessionReport r = BuildSessionReport(tmp.path(), {}, {});
  const Chart* fam = FindChart(r, "plot-residual-families");
  ASSERT_NE(fam, nullptr);
  EXPECT_EQ(fam->categories,
            (std::vector<std::string>{"corners_c1_world", "corners_c2_world", "sliding_dots",
                                      "reflected_dots", "held-out dots"}));
  // Normal quantiles: RMS about 1.
  for (size_t k = 0; k + 1 < fam->categories.size(); ++k)
    EXPECT_NEAR(fam->series[0].y[k], 1.0, 0.05) << fam->categories[k];
  EXPECT_NEAR(fam->series[1].y[0], std::sqrt(1.1), 1e-12);  // sqrt(variance factor)
  const Chart* h = FindChart(r, "plot-whitened-histogram");
  ASSERT_NE(h, nullptr);
  ASSERT_EQ(h->series.size(), 5u);  // corners, sliding dots, reflected dots, held-out, N(0,1)
  EXPECT_NE(h->series[0].name.find("corners (800)"), std::string::npos) << h->series[0].name;
  for (size_t k = 0; k + 1 < h->series.size(); ++k) {
    double integral = 0;
    for (double y : h->series[k].y) integral += y * 0.25;
    EXPECT_NEAR(integral, 1.0, 1e-12) << h->series[k].name;
  }
  // The six bins over [-0.75, 0.75] hold the normal's mass there, erf(0.75 / sqrt 2) = 54.7 %.
  double central = 0;
  for (size_t i = 0; i < h->series[0].x.size(); ++i)
    if (std::abs(h->series[0].x[i]) < 0.7) central += h->series[0].y[i] * 0.25;
  EXPECT_NEAR(central, std::erf(0.75 / std::sqrt(2.0)), 0.03);
}

TEST(SessionReport, OlderFolderWithoutJointWhiteningSkipsTheSigmaLines) {
  testing::TempDir tmp;
  SolvedFolder(tmp.path(), 1.0);
  fs::remove(tmp.path() / "results" / "validation_dots.csv");
  const SessionReport r = BuildSessionReport(tmp.path(), {}, {});
  EXPECT_EQ(Find(r, "sigma honest"), nullptr);
  EXPECT_EQ(Find(r, "held-out dots inside"), nullptr);
  EXPECT_NE(r.text.find("SKIPPED: held-out residual vectors"), std::string::npos) << r.text;
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

#include "sessions/report/session_report.h"

#include <yaml-cpp/yaml.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "common/text_io.h"
#include "processing/hall/calibration.h"
#include "processing/hall/phase_profile.h"
#include "processing/hall/time_base.h"
#include "processing/solver/mle.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/report/build_info.h"
#include "sessions/results/finish_steps.h"
#include "sessions/store/session_store.h"

namespace msmcal::report {

namespace fs = std::filesystem;

namespace {

constexpr const char* kBlue = "#1f77b4";
constexpr const char* kOrange = "#ff7f0e";
constexpr const char* kGreen = "#2ca02c";
constexpr const char* kRed = "#d62728";
constexpr const char* kPurple = "#9467bd";
constexpr const char* kGrey = "#7f7f7f";

std::string Fmt(const char* format, double v) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

// The second table of hall_model.yaml: one row per model fitted (results::ReadHallModelYaml reads
// the final model only).
struct HallComparisonRow {
  std::string model;
  double test_rms[3] = {NAN, NAN, NAN}, test_rms_std[3] = {NAN, NAN, NAN};
  double train_rms[3] = {NAN, NAN, NAN};
  double delta_t_s = NAN, delta_t_std_s = NAN;
};

double Num(const YAML::Node& n, const char* key) {
  return n && n[key] && n[key].IsScalar() ? n[key].as<double>() : NAN;
}

void Triple(const YAML::Node& n, double out[3]) {
  out[0] = Num(n, "alpha_deg"), out[1] = Num(n, "beta_deg"), out[2] = Num(n, "trans_mm");
}

std::vector<HallComparisonRow> ReadHallComparison(const fs::path& file) {
  std::vector<HallComparisonRow> rows;
  try {
    const YAML::Node root = YAML::LoadFile(file.string());
    for (const auto& m : root["comparison"]) {
      HallComparisonRow r;
      r.model = m["model"].as<std::string>();
      Triple(m["test_rms"], r.test_rms);
      Triple(m["test_rms_std"], r.test_rms_std);
      Triple(m["train_rms"], r.train_rms);
      r.delta_t_s = Num(m, "delta_t_s");
      r.delta_t_std_s = Num(m, "delta_t_std_s");
      rows.push_back(r);
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(file.string() + ": comparison: " + e.what());
  }
  return rows;
}

// Readings lost on the link: gaps in the MCU time stamps longer than 1.5 sample periods.
long long LostReadings(const dataset::HallRecording& rec, long long* expected) {
  std::vector<double> t;
  t.reserve(rec.readings.size());
  for (const auto& r : rec.readings) t.push_back(r.mcu_time_us);
  const double period = hall::MedianSpacing(t);
  long long lost = 0;
  if (period > 0)
    for (size_t i = 1; i < t.size(); ++i) {
      const double gap = (t[i] - t[i - 1]) / period;
      if (gap > 1.5) lost += std::llround(gap) - 1;
    }
  *expected += static_cast<long long>(t.size()) + lost;
  return lost;
}

ChartSeries Series(const std::string& name, ChartSeries::Style style, const char* colour) {
  ChartSeries s;
  s.name = name;
  s.style = style;
  s.colour = colour;
  return s;
}

// alpha/beta/trans against time with +-sigma bands (mirror_planes.csv, sorted by t).
void PoseTimeCharts(const std::vector<dataset::MirrorPlaneRow>& planes,
                    std::vector<Chart>* charts) {
  std::vector<dataset::MirrorPlaneRow> p = planes;
  std::sort(p.begin(), p.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  const char* names[3] = {"alpha", "beta", "trans"};
  const char* units[3] = {"deg", "deg", "mm"};
  const char* colours[3] = {kBlue, kOrange, kGreen};
  for (int k = 0; k < 3; ++k) {
    Chart c;
    c.id = std::string("plot-pose-") + names[k];
    c.title = std::string(names[k]) + " per trigger against pattern time, with its +-1 sigma band";
    c.x_label = "pattern time (s)";
    c.y_label = std::string(names[k]) + " (" + units[k] + ")";
    ChartSeries s =
        Series(std::string(names[k]) + " (solver)", ChartSeries::Style::kPoints, colours[k]);
    for (const auto& r : p) {
      const double v = k == 0 ? r.alpha_deg : k == 1 ? r.beta_deg : r.trans_mm;
      const double sg = k == 0 ? r.sigma_alpha_deg : k == 1 ? r.sigma_beta_deg : r.sigma_trans_mm;
      s.x.push_back(r.t_s);
      s.y.push_back(v);
      s.y_lo.push_back(v - sg);
      s.y_hi.push_back(v + sg);
    }
    c.series.push_back(s);
    c.caption =
        "Each scan plane's pose from results/mirror_planes.csv; the band is +-1 sigma "
        "(the solver's covariance, {0}'s error included).";
    charts->push_back(c);
  }
}

// What the Hall recordings and the model give the report beyond hall_model.yaml's figures.
struct HallAnalysis {
  bool ok = false;
  std::string error;
  double reading_noise_uT[3] = {0, 0, 0};
  double floor[3] = {0, 0, 0};
  bool floor_from_linear = false;
  std::vector<double> dt_grid_s, dt_cost;
  std::vector<Chart> charts;
};

HallAnalysis AnalyseHall(const dataset::Recording& rec,
                         const std::vector<dataset::MirrorPlaneRow>& planes,
                         const results::HallModelFile& model, const fs::path& dir) {
  HallAnalysis a;
  try {
    const results::HallCalibrationSetup setup =
        results::MakeHallCalibrationSetup(rec, planes, dir.string());
    const hall::HallCalibrationOptions defaults;  // the calibration's (not stored in the file)
    const double period = setup.pattern_period_s;
    const hall::TimeBase tba = hall::FitTimeBase(setup.actual.clock_edges_us, period);
    const hall::TimeBase tbb = hall::FitTimeBase(setup.background.clock_edges_us, period);
    std::vector<double> ta, tb;
    std::vector<Eigen::Vector3d> ba, bb;
    hall::MapReadings(setup.actual, tba, &ta, &ba);
    hall::MapReadings(setup.background, tbb, &tb, &bb);
    hall::Foreground fg;
    fg.actual = hall::PhaseProfile::Build(ta, ba, period, defaults.profile);
    fg.background = hall::PhaseProfile::Build(tb, bb, period, defaults.profile);
    // Single-reading noise: the actual readings about their own phase profile. The profile
    // averages readings_per_bin readings, so the residual's variance is (1 - 1/n) of the noise's.
    const double n = std::max(1.5, defaults.profile.readings_per_bin);
    Eigen::Vector3d ss = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < ta.size(); ++i) ss += (ba[i] - fg.actual.At(ta[i])).cwiseAbs2();
    const Eigen::Vector3d sigma_b = (ss / std::max<size_t>(1, ta.size()) / (1 - 1 / n)).cwiseSqrt();
    // Propagated through the model: J = d pose / d b (central differences) over the period. A
    // model that does not read the field (sine: time only) has J = 0; its floor is then the
    // linear model's refitted at the same delta_t, what one reading can tell at best.
    const hall::HallModel& m = model.model;
    const auto fgf = [&fg](double t) { return fg.Value(t); };
    hall::HallFitOptions fo;
    fo.fast_frequency_hz = setup.fast_frequency_hz;
    fo.slow_frequency_hz = setup.slow_frequency_hz;
    fo.pattern_period_s = period;
    auto propagate = [&](const hall::HallModel& model_used) {
      Eigen::Vector3d f2 = Eigen::Vector3d::Zero();
      const int steps = 64;
      for (int i = 0; i < steps; ++i) {
        const double tau = period * i / steps;
        const Eigen::Vector3d b = fg.Value(tau);
        for (int k = 0; k < 3; ++k) {
          const double h = std::max(1e-3, 1e-3 * std::abs(b[k]));
          Eigen::Vector3d bp = b, bm = b;
          bp[k] += h, bm[k] -= h;
          const Eigen::Vector3d d =
              (model_used.Predict(bp, tau) - model_used.Predict(bm, tau)) / (2 * h);
          f2 += (d * sigma_b[k]).cwiseAbs2();
        }
      }
      return Eigen::Vector3d(f2 / steps);
    };
    Eigen::Vector3d floor2 = propagate(m);
    if (floor2.maxCoeff() <= 0) {
      fo.delta_t_min_s = m.delta_t_s;
      fo.delta_t_max_s = m.delta_t_s + 1e-9;
      fo.grid_step_s = 1e-9;
      floor2 =
          propagate(hall::FitHallModel(hall::HallModelKind::kLinear, setup.poses, fgf, fo).model);
      a.floor_from_linear = true;
    }
    for (int k = 0; k < 3; ++k) {
      a.reading_noise_uT[k] = sigma_b[k];
      a.floor[k] = std::sqrt(floor2[k]);
    }

    // The model's fit per output: the solver's poses and the model over one period.
    const char* names[3] = {"alpha", "beta", "trans"};
    const char* units[3] = {"deg", "deg", "mm"};
    for (int k = 0; k < 3; ++k) {
      Chart c;
      c.id = std::string("plot-hall-fit-") + names[k];
      c.title = std::string("Hall model fit: ") + names[k] + " over one pattern period";
      c.x_label = "pattern time (s)";
      c.y_label = std::string(names[k]) + " (" + units[k] + ")";
      ChartSeries curve = Series(std::string("model (") + hall::ToString(m.kind) + ")",
                                 ChartSeries::Style::kLine, kRed);
      const int samples = 400;
      for (int i = 0; i <= samples; ++i) {
        const double t = period * i / samples;  // pose time; the field is read at t + delta_t
        const double tau = t + m.delta_t_s;
        curve.x.push_back(t);
        curve.y.push_back(m.Predict(fg.Value(tau), tau)[k]);
      }
      ChartSeries pts = Series("solver poses", ChartSeries::Style::kPoints, kBlue);
      for (const auto& p : setup.poses) {
        double t = std::fmod(p.t_s, period);
        if (t < 0) t += period;
        pts.x.push_back(t);
        pts.y.push_back(p.pose[k]);
      }
      c.series = {curve, pts};
      c.caption =
          "The final model on the foreground field of every reading, against the poses it "
          "was trained on.";
      a.charts.push_back(c);
    }

    // delta_t cost curve: the chosen model refitted at each delta_t of a grid.
    Chart cost;
    cost.id = "plot-delta-t-cost";
    cost.title = "delta_t cost curve (" + std::string(hall::ToString(m.kind)) + " model)";
    cost.x_label = "delta_t (ms)";
    cost.y_label = "fit cost (sum of squared residuals)";
    cost.y_log = true;
    ChartSeries cs = Series("cost at fixed delta_t", ChartSeries::Style::kLine, kBlue);
    double cmin = INFINITY, cmax = 0;
    const double lo = defaults.delta_t_min_s, hi = defaults.delta_t_max_s;
    for (int i = 0; i <= 80; ++i) {
      const double dt = lo + (hi - lo) * i / 80;
      fo.delta_t_min_s = dt;
      fo.delta_t_max_s = dt + 1e-9;
      fo.grid_step_s = 1e-9;
      const hall::HallFitResult r = hall::FitHallModel(m.kind, setup.poses, fgf, fo);
      a.dt_grid_s.push_back(dt);
      a.dt_cost.push_back(r.cost);
      cs.x.push_back(dt * 1e3);
      cs.y.push_back(std::max(r.cost, 1e-300));
      cmin = std::min(cmin, r.cost), cmax = std::max(cmax, r.cost);
    }
    ChartSeries mark = Series("estimate", ChartSeries::Style::kLine, kRed);
    mark.x = {m.delta_t_s * 1e3, m.delta_t_s * 1e3};
    mark.y = {std::max(cmin, 1e-300), std::max(cmax, 1e-300)};
    cost.series = {cs, mark};
    cost.caption =
        "The chosen model's least-squares cost with delta_t held fixed; the estimate "
        "(red) should sit in a clear minimum inside the search range.";
    a.charts.push_back(cost);

    // Clock-edge residuals of both recordings.
    Chart edges;
    edges.id = "plot-clock-edges";
    edges.title = "Clock-edge residuals (time base fit)";
    edges.x_label = "edge index";
    edges.y_label = "residual (us)";
    auto edge_series = [&](const dataset::HallRecording& r, const hall::TimeBase& tbase,
                           const char* name, const char* colour) {
      ChartSeries s = Series(name, ChartSeries::Style::kPoints, colour);
      for (double e : r.clock_edges_us) {
        const double k = std::round(tbase.GeneratorTime(e) / period);
        s.x.push_back(k);
        s.y.push_back(e - tbase.McuTime(k * period));
      }
      return s;
    };
    edges.series = {edge_series(setup.actual, tba, "actual", kBlue),
                    edge_series(setup.background, tbb, "background", kOrange)};
    edges.caption =
        "Each MCU clock edge minus the fitted time base (offset and rate); jitter is "
        "their RMS.";
    a.charts.push_back(edges);
    a.ok = true;
  } catch (const std::exception& e) {
    a.error = e.what();
  }
  return a;
}

// The largest 1, 2 or 5 x 10^k not above v (v > 0).
double NiceFloor(double v) {
  const double p = std::pow(10.0, std::floor(std::log10(v)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * p <= v) return m * p;
  return p;
}

// Held-out residual vectors on the image: from each dot's predicted position towards its
// measured one, magnified by `scale`, with its 1-sigma ellipse (the 2x2 covariance, same
// magnification) and the image's outline.
Chart ResidualVectorChart(const std::vector<results::ValidationDotRow>& dots,
                          const geometry::CameraModel* camera) {
  Chart c;
  c.id = "plot-validation-vectors";
  c.x_label = "image x (px)";
  c.y_label = "image y (px)";
  c.y_reversed = true;
  double w = camera ? camera->width : 0, h = camera ? camera->height : 0;
  std::vector<double> len;
  for (const auto& d : dots) {
    len.push_back((d.observed_px - d.predicted_px).norm());
    w = std::max(w, d.predicted_px.x()), h = std::max(h, d.predicted_px.y());
  }
  std::sort(len.begin(), len.end());
  const double median = len.empty() ? 0 : len[len.size() / 2];
  // The median vector drawn as 4 % of the image's diagonal.
  const double scale = median > 0 ? NiceFloor(0.04 * std::hypot(w, h) / median) : 1;
  const std::string times = "x" + Fmt("%g", scale);
  c.title = "Held-out residual vectors on the image (errors " + times + ")";
  ChartSeries vec = Series("measured - predicted, " + times +
                               " (1 px of error = " + Fmt("%g", scale) + " px on the plot)",
                           ChartSeries::Style::kLine, kRed);
  ChartSeries ell = Series("predicted 1-sigma ellipse, " + times, ChartSeries::Style::kLine, kGrey);
  ChartSeries pred = Series("predicted dot", ChartSeries::Style::kPoints, kBlue);
  for (const auto& d : dots) {
    const Eigen::Vector2d tip = d.predicted_px + scale * (d.observed_px - d.predicted_px);
    vec.x.insert(vec.x.end(), {d.predicted_px.x(), tip.x(), NAN});
    vec.y.insert(vec.y.end(), {d.predicted_px.y(), tip.y(), NAN});
    pred.x.push_back(d.predicted_px.x());
    pred.y.push_back(d.predicted_px.y());
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(d.cov_px2);
    const Eigen::Matrix2d axes =
        es.eigenvectors() * es.eigenvalues().cwiseMax(0).cwiseSqrt().asDiagonal();
    for (int k = 0; k <= 24; ++k) {
      const double a = 2 * M_PI * k / 24;
      const Eigen::Vector2d p =
          d.predicted_px + scale * axes * Eigen::Vector2d(std::cos(a), std::sin(a));
      ell.x.push_back(p.x());
      ell.y.push_back(p.y());
    }
    ell.x.push_back(NAN);
    ell.y.push_back(NAN);
  }
  ChartSeries frame = Series("image outline", ChartSeries::Style::kLine, kGreen);
  frame.x = {0, w, w, 0, 0};
  frame.y = {0, 0, h, h, 0};
  c.series = {vec, ell, pred, frame};
  c.caption =
      "Each held-out dot (results/validation_dots.csv): the arrow runs from where the proposed "
      "model predicts it to where it was measured, the error magnified " +
      times + "; the grey ellipse is its predicted 1-sigma covariance, magnified alike.";
  return c;
}

// Whitened residuals by family: the RMS of each family's whitened components and their
// histograms against N(0, 1); the held-out dots (jointly whitened) as one more family.
void WhitenedResidualCharts(const std::vector<solver::WhitenedResidual>& residuals,
                            const std::vector<results::ValidationDotRow>& dots,
                            const results::MirrorPosesSummary& summary,
                            std::vector<Chart>* charts) {
  std::array<std::vector<double>, solver::kNumFamilies> by_family;
  for (const auto& r : residuals) {
    by_family[r.family].push_back(r.whitened.x());
    by_family[r.family].push_back(r.whitened.y());
  }
  std::vector<double> held_out;
  for (const auto& d : dots) {
    held_out.push_back(d.joint_whitened.x());
    held_out.push_back(d.joint_whitened.y());
  }
  auto rms = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x * x;
    return v.empty() ? NAN : std::sqrt(s / v.size());
  };
  Chart fam;
  fam.id = "plot-residual-families";
  fam.title = "Whitened residuals by family (RMS of residual / its sigma)";
  fam.x_label = "residual family";
  fam.y_label = "whitened RMS (1)";
  ChartSeries got = Series("RMS whitened by the covariance used", ChartSeries::Style::kBar, kBlue);
  ChartSeries factor =
      Series("sqrt(variance factor): input covariance scale", ChartSeries::Style::kBar, kOrange);
  ChartSeries want = Series("expected (honest covariances)", ChartSeries::Style::kLine, kGrey);
  for (int f = 0; f < solver::kNumFamilies; ++f) {
    if (by_family[f].empty()) continue;
    fam.categories.push_back(solver::MleFamilyName(f));
    got.y.push_back(rms(by_family[f]));
    double vf = NAN;
    for (const auto& v : summary.variance_factors)
      if (v.name == solver::MleFamilyName(f)) vf = std::sqrt(std::max(0.0, v.variance_factor));
    factor.y.push_back(vf);
    want.y.push_back(1.0);
  }
  if (!held_out.empty()) {
    fam.categories.push_back("held-out dots");
    got.y.push_back(rms(held_out));
    factor.y.push_back(NAN);
    want.y.push_back(1.0);
  }
  fam.series = {got, factor, want};
  fam.caption =
      "Blue: RMS of every fitted residual whitened by the covariance the MLE used for it "
      "(results/residuals.csv; its variance factor included, so about sqrt(1 - leverage) "
      "when honest), and of the held-out dots' errors whitened jointly "
      "(results/validation_dots.csv). Orange: sqrt of the family's posterior variance factor "
      "(summary.json), how far the input covariances had to be scaled: 1 when they were "
      "honest.";
  charts->push_back(fam);

  // Histograms (density) of the whitened components: corners, sliding-plane dots, reflected
  // dots (both reflected families), held-out dots.
  struct Group {
    const char* name;
    const char* colour;
    std::vector<double> v;
  };
  std::vector<Group> groups = {{"corners", kBlue, {}},
                               {"sliding-plane dots", kOrange, {}},
                               {"reflected dots", kGreen, {}},
                               {"held-out dots (jointly whitened)", kPurple, held_out}};
  for (int f = 0; f < solver::kNumFamilies; ++f) {
    const int g = f <= solver::kCornersC2World ? 0 : f == solver::kSlidingDots ? 1 : 2;
    groups[g].v.insert(groups[g].v.end(), by_family[f].begin(), by_family[f].end());
  }
  const double lim = 5, width = 0.25;
  const int bins = static_cast<int>(2 * lim / width);
  Chart hist;
  hist.id = "plot-whitened-histogram";
  hist.title = "Whitened residuals by family against N(0, 1)";
  hist.x_label = "whitened residual (sigma)";
  hist.y_label = "density (1/sigma)";
  for (const Group& g : groups) {
    if (g.v.empty()) continue;
    std::vector<int> counts(bins, 0);
    for (double x : g.v)
      ++counts[std::clamp(static_cast<int>(std::floor((x + lim) / width)), 0, bins - 1)];
    ChartSeries s = Series(std::string(g.name) + " (" + std::to_string(g.v.size()) + ")",
                           ChartSeries::Style::kStep, g.colour);
    for (int k = 0; k < bins; ++k) {
      s.x.push_back(-lim + (k + 0.5) * width);
      s.y.push_back(counts[k] / (g.v.size() * width));
    }
    hist.series.push_back(s);
  }
  ChartSeries normal = Series("N(0, 1)", ChartSeries::Style::kLine, kGrey);
  for (int k = 0; k <= 200; ++k) {
    const double x = -lim + 2 * lim * k / 200;
    normal.x.push_back(x);
    normal.y.push_back(std::exp(-x * x / 2) / std::sqrt(2 * M_PI));
  }
  hist.series.push_back(normal);
  hist.caption =
      "Each component of every whitened residual (both image axes), by family, as a density "
      "(values beyond +-5 in the end bins); the grey curve is what honest covariances give.";
  charts->push_back(hist);
}

}  // namespace

SessionReport BuildSessionReport(const fs::path& dir, const ReportOptions& options,
                                 const TruthSource& truth_source) {
  SessionReport rep;
  const fs::path res = dir / "results";
  const std::unique_ptr<TruthComparison> truth = truth_source ? truth_source(dir) : nullptr;
  const bool have_truth = truth != nullptr;
  if (!have_truth)
    rep.skipped.push_back("comparison with truth: no truth/ folder (not a simulated session)");
  rep.provenance = ResolveProvenance(dir, options.session_process);

  std::optional<dataset::Recording> rec;
  if (fs::exists(dir / "session.yaml")) {
    // A Hall recording that cannot be read (cut short, a fault) must not cost the report its
    // other parts: read without hall/ then, and say so.
    try {
      rec = interchange::ReadRecording(dir, interchange::ReadParts{/*hall=*/true, /*marg=*/false});
    } catch (const std::exception& e) {
      rec = interchange::ReadRecording(dir, interchange::ReadParts{/*hall=*/false, /*marg=*/false});
      rep.skipped.push_back(
          std::string("Hall recordings unreadable (noise floor, lost readings and "
                      "Hall plots left out): ") +
          e.what());
    }
    rep.triggers_planned = static_cast<int>(rec->triggers.size());
  } else {
    rep.skipped.push_back("session.yaml missing: triggers planned and Hall recordings unknown");
  }

  std::vector<Chart>& charts = rep.charts;
  std::vector<dataset::MirrorPlaneRow> planes;
  std::vector<results::ValidationDetailRow> detail;
  // ---------------------------------------------------------------- Table I: planes, validation
  const bool solved_here = results::SummaryJsonHas(res / "summary.json", "mirror_poses");
  if (fs::exists(res / "mirror_planes.csv") && !solved_here)
    rep.skipped.push_back(
        "results/summary.json has no mirror_poses (the mirror planes were not solved in this "
        "folder): Table I and the plane plots left out");
  if (fs::exists(res / "mirror_planes.csv") && solved_here) {
    rep.have_planes = true;
    planes = results::ReadMirrorPlanesCsv(res / "mirror_planes.csv");
    rep.planes = static_cast<int>(planes.size());
    const results::MirrorPosesSummary s = results::ReadMirrorPosesSummary(res / "summary.json");
    rep.validation_rms_deg = s.validation_rms_deg;
    rep.validation_rms_px = s.validation_rms_px;
    rep.baseline_rms_deg = s.baseline_validation_rms_deg;
    rep.baseline_rms_px = s.baseline_validation_rms_px;
    rep.normalised_validation_rms = s.validation_normalised_rms;
    rep.mean_spanning_angle_deg = s.mean_spanning_angle_deg;
    rep.validation_count = s.validation_count;

    // Scan pattern (the truth adds its series).
    Chart scan;
    scan.id = "plot-scan-pattern";
    scan.title = "Scan pattern: mirror pose per trigger";
    scan.x_label = "alpha (deg)";
    scan.y_label = "beta (deg)";
    ChartSeries est = Series("estimated", ChartSeries::Style::kPoints, kRed);
    for (const auto& p : planes) est.x.push_back(p.alpha_deg), est.y.push_back(p.beta_deg);
    scan.series.push_back(est);
    scan.caption = "Estimated poses (results/mirror_planes.csv)";
    scan.caption += have_truth ? " and the simulator's truth in the solver's {0}." : ".";
    charts.push_back(scan);
    if (have_truth) truth->CompareMirrorPlanes(planes, &rep, &charts);
    PoseTimeCharts(planes, &charts);

    // Held-out dots on the image, jointly whitened (results/validation_dots.csv), and every
    // fitted residual whitened (results/residuals.csv).
    std::vector<results::ValidationDotRow> dots;
    const bool have_dots = fs::exists(res / "validation_dots.csv");
    if (have_dots) {
      dots = results::ReadValidationDotsCsv(res / "validation_dots.csv");
      charts.push_back(ResidualVectorChart(dots, rec ? &rec->camera : nullptr));
    } else {
      rep.skipped.push_back(
          "held-out residual vectors, joint whitening and the sigma honesty lines: "
          "results/validation_dots.csv missing (solved by an older msmcal: msmcal solve again)");
    }
    if (fs::exists(res / "residuals.csv")) {
      WhitenedResidualCharts(results::ReadResidualsCsv(res / "residuals.csv"), dots, s, &charts);
    } else {
      rep.skipped.push_back(
          "whitened residuals by family: results/residuals.csv missing (solved by an older "
          "msmcal: msmcal solve again)");
    }

    if (fs::exists(res / "validation_detail.csv")) {
      detail = results::ReadValidationDetailCsv(res / "validation_detail.csv");
      // Normalised-error histogram: r = sqrt(e^T C^-1 e) is Rayleigh when honest, for the
      // jointly whitened errors (independent dots) when they are there, else the marginal ones.
      std::vector<double> r;
      if (have_dots)
        for (const auto& d : dots) r.push_back(d.joint_whitened.norm());
      else
        for (const auto& d : detail) r.push_back(std::sqrt(2.0) * d.normalised_error);
      const double top = std::max(4.0, r.empty() ? 0.0 : *std::max_element(r.begin(), r.end()));
      const int bins = std::clamp(static_cast<int>(std::sqrt(double(r.size()))) + 2, 6, 30);
      const double w = top / bins;
      Chart h;
      h.id = "plot-normalised-errors";
      h.title = "Held-out dots: Mahalanobis distance of the error";
      h.x_label = "sqrt(e^T C^-1 e) (sigma)";
      h.y_label = "dots per bin (count)";
      ChartSeries got = Series("held-out dots", ChartSeries::Style::kStep, kPurple);
      ChartSeries want =
          Series("expected (Rayleigh, chi2 with 2 dof)", ChartSeries::Style::kLine, kGrey);
      std::vector<int> counts(bins, 0);
      for (double v : r) ++counts[std::min(bins - 1, static_cast<int>(v / w))];
      for (int k = 0; k < bins; ++k) {
        got.x.push_back((k + 0.5) * w);
        got.y.push_back(counts[k]);
      }
      for (int k = 0; k <= 100; ++k) {
        const double x = top * k / 100;
        want.x.push_back(x);
        want.y.push_back(r.size() * w * x * std::exp(-x * x / 2));
      }
      h.series = {got, want};
      h.caption =
          have_dots
              ? "Each held-out dot's error whitened jointly with the other held-out dots (its "
                "error given the dots before it, over its conditional 2x2 covariance: "
                "independent across dots); the grey curve is the count honest covariances give."
              : "Each held-out dot's error whitened by its own predicted 2x2 covariance "
                "(results/validation_dots.csv missing: dots of one beam are correlated); the "
                "grey curve is the count an honest covariance gives.";
      charts.push_back(h);

      Chart sc;
      sc.id = "plot-validation-sigma";
      sc.title = "Held-out dots: error against predicted sigma";
      sc.x_label = "predicted sigma (px)";
      sc.y_label = "error (px)";
      ChartSeries pts = Series("proposed", ChartSeries::Style::kPoints, kPurple);
      ChartSeries base = Series("baseline", ChartSeries::Style::kPoints, kGrey);
      ChartSeries one = Series("error = sigma", ChartSeries::Style::kLine, kGreen);
      double smax = 0;
      for (const auto& d : detail) {
        pts.x.push_back(d.predicted_sigma_px), pts.y.push_back(d.err_px);
        base.x.push_back(d.predicted_sigma_px), base.y.push_back(d.baseline_err_px);
        smax = std::max(smax, d.predicted_sigma_px);
      }
      one.x = {0, smax};
      one.y = {0, smax};
      sc.series = {pts, base, one};
      sc.caption =
          "Each held-out dot's image error (proposed and baseline model) against the "
          "sigma the proposed model predicts for it.";
      charts.push_back(sc);

      Chart byj;
      byj.id = "plot-validation-residuals";
      byj.title = "Held-out residuals per trigger";
      byj.x_label = "trigger j";
      byj.y_label = "error (px)";
      ChartSeries e = Series("proposed", ChartSeries::Style::kPoints, kPurple);
      for (const auto& d : detail) {
        e.x.push_back(d.j);
        e.y.push_back(d.err_px);
        e.y_lo.push_back(0);
        e.y_hi.push_back(d.predicted_sigma_px);
      }
      // Bands need ascending x.
      std::vector<size_t> idx(e.x.size());
      for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
      std::sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return e.x[a] < e.x[b]; });
      ChartSeries sorted = e;
      for (size_t i = 0; i < idx.size(); ++i) {
        sorted.x[i] = e.x[idx[i]], sorted.y[i] = e.y[idx[i]];
        sorted.y_lo[i] = e.y_lo[idx[i]], sorted.y_hi[i] = e.y_hi[idx[i]];
      }
      byj.series = {sorted};
      byj.caption =
          "Held-out beam's image error per trigger; the band reaches its predicted "
          "1-sigma.";
      charts.push_back(byj);

      // The rules take independent errors: the jointly whitened ones. The marginal normalised
      // errors share the held-out beam's (and c2's, and each plane's) error: judged as N
      // independent dots one beam error decides the verdict (the tiny demo: all 18 dots
      // 0.21 px off in one direction, 1.5-2.2 marginal sigma, 0 of 18 inside 1 sigma;
      // docs/report.md).
      if (have_dots) {
        std::vector<double> ne;
        for (const auto& d : dots) ne.push_back(d.joint_whitened.norm() / std::sqrt(2.0));
        rep.verdict.push_back(JudgeNees(ne));
        rep.verdict.push_back(JudgeEllipseCoverage(ne));
        for (size_t k = rep.verdict.size() - 2; k < rep.verdict.size(); ++k)
          rep.verdict[k].figure += " (errors whitened jointly over the held-out dots)";
      }
    } else {
      rep.skipped.push_back(
          "held-out beam plots and sigma honesty: "
          "results/validation_detail.csv missing");
    }
    if (rec) rep.verdict.push_back(JudgePlanes(rep.planes, rep.triggers_planned));

    // Frames dropped, with the main reason.
    std::map<std::string, int> reasons;
    for (const auto& d : s.dropped_frames) ++reasons[d.reason];
    std::string main_reason;
    int main_count = 0;
    for (const auto& [r, c] : reasons)
      if (c > main_count) main_reason = r, main_count = c;
    const int frames = rec ? static_cast<int>(rec->step1.size() + rec->step2.size()) : 0;
    rep.verdict.push_back(JudgeDroppedFrames(static_cast<int>(s.dropped_frames.size()), frames,
                                             main_reason, main_count));
    if (!s.dropped_frames.empty()) {
      Table t;
      t.id = "table-dropped-frames";
      t.title = "Frames dropped by the solver";
      t.header = {"frame", "reason"};
      for (const auto& d : s.dropped_frames) t.rows.push_back({d.file, d.reason});
      t.caption =
          "results/detections.csv has every frame's figures; results/diagnostics/ the "
          "annotated images.";
      rep.tables.push_back(t);
    }

    Table t1;
    t1.id = "table-one";
    t1.title = "Table I style: mirror poses";
    t1.header = {"model", "validation error (deg RMS)", "validation error (px RMS)",
                 "normalised validation RMS"};
    t1.rows.push_back(
        {"baseline", Fmt("%.4f", rep.baseline_rms_deg), Fmt("%.3f", rep.baseline_rms_px), "-"});
    t1.rows.push_back({"proposed", Fmt("%.4f", rep.validation_rms_deg),
                       Fmt("%.3f", rep.validation_rms_px),
                       Fmt("%.2f", rep.normalised_validation_rms)});
    t1.caption = std::to_string(rep.planes) + " scan planes, " +
                 std::to_string(rep.validation_count) + " held-out dots, mean spanning angle " +
                 Fmt("%.2f", rep.mean_spanning_angle_deg) + " deg.";
    if (s.rms_sigma_normal_world_deg >= 0) {  // summaries since session 24
      // In {W}: step 1's common beam tilt, which step 2 cannot see and {0} cancels.
      std::string beams;
      for (double b : s.beam_direction_sigma_deg)
        beams += (beams.empty() ? "" : " / ") + Fmt("%.4f", b);
      t1.caption += " In the world frame the normals are uncertain by " +
                    Fmt("%.4f", s.rms_sigma_normal_world_deg) +
                    " deg (RMS sigma) and the beam directions by " + beams +
                    " deg: step 1's tilt of the beams, shared by every plane, which the poses "
                    "in {0} leave out.";
    }
    if (have_truth) {
      t1.header.insert(t1.header.end(),
                       {"plane normal vs truth (deg RMS)", "alpha / beta vs truth (deg RMS)",
                        "trans vs truth (mm RMS)"});
      t1.rows[0].insert(t1.rows[0].end(), {"-", "-", "-"});
      t1.rows[1].insert(t1.rows[1].end(), {Fmt("%.4f", rep.normal_rms_vs_truth_deg),
                                           Fmt("%.4f", rep.alpha_rms_vs_truth_deg) + " / " +
                                               Fmt("%.4f", rep.beta_rms_vs_truth_deg),
                                           Fmt("%.4f", rep.trans_rms_vs_truth_mm)});
    }
    rep.tables.insert(rep.tables.begin(), t1);
  } else {
    rep.skipped.push_back(
        "Table I figures: results/mirror_planes.csv or summary.json missing "
        "(solver did not run or failed)");
  }

  // ------------------------------------------------------------------ Table II: the Hall model
  const fs::path hall_yaml = res / "hall_model.yaml";
  if (fs::exists(hall_yaml)) {
    rep.have_hall = true;
    const results::HallModelFile model = results::ReadHallModelYaml(hall_yaml);
    rep.hall_model = hall::ToString(model.model.kind);
    rep.delta_t_s = model.model.delta_t_s;  // files written before time_offset existed
    if (model.time_offset) {
      rep.delta_t_identified = model.time_offset->identified();
      rep.delta_t_s = rep.delta_t_identified ? model.time_offset->delta_t_s : NAN;
      rep.delta_t_reason = model.time_offset->reason;
    }
    if (model.test_rms)
      for (int k = 0; k < 3; ++k) rep.test_rms[k] = (*model.test_rms)[k];
    rep.delta_t_truth_s = have_truth ? truth->TrueDeltaT() : 0.0;
    const std::vector<HallComparisonRow> comparison = ReadHallComparison(hall_yaml);
    rep.delta_t_sigma_s = NAN;
    Table t2;
    t2.id = "table-two";
    t2.title = "Table II style: Hall models";
    t2.header = {"model", "alpha test RMS (deg)", "beta test RMS (deg)", "trans test RMS (mm)",
                 "delta_t (ms)"};
    for (const auto& c : comparison) {
      if (c.model == rep.hall_model && !model.time_offset) rep.delta_t_sigma_s = c.delta_t_std_s;
      auto pm = [](double m, double s, const char* f) { return Fmt(f, m) + " +- " + Fmt(f, s); };
      t2.rows.push_back({c.model + (c.model == rep.hall_model ? " (chosen)" : ""),
                         pm(c.test_rms[0], c.test_rms_std[0], "%.4f"),
                         pm(c.test_rms[1], c.test_rms_std[1], "%.4f"),
                         pm(c.test_rms[2], c.test_rms_std[2], "%.4f"),
                         pm(c.delta_t_s * 1e3, c.delta_t_std_s * 1e3, "%.3f")});
    }
    t2.caption =
        "Mean +- std over the " +
        (model.repetitions > 0 ? std::to_string(model.repetitions) + " " : std::string()) +
        (model.leave_one_out ? "leave-one-out splits (each pose held out once)"
                             : "random train/test splits") +
        " (results/hall_model.yaml). Final "
        "model: " +
        rep.hall_model +
        (rep.delta_t_identified ? ", delta_t " + Fmt("%.4f ms", rep.delta_t_s * 1e3) +
                                      (model.time_offset && model.time_offset->method ==
                                                                hall::DeltaTMethod::kDrivePhases
                                           ? " (identified by the drives' phases)"
                                           : "")
                                : ", delta_t not identified (" + rep.delta_t_reason + ")") +
        (have_truth ? Fmt(" (truth %.4f ms)", rep.delta_t_truth_s * 1e3) : "") + ".";
    rep.tables.push_back(t2);

    if (model.time_offset && model.time_offset->identified())
      rep.delta_t_sigma_s = model.time_offset->sigma_s;
    const hall::HallCalibrationOptions defaults;
    if (rep.delta_t_identified) {
      rep.verdict.push_back(JudgeDeltaT(rep.delta_t_s, rep.delta_t_sigma_s, defaults.delta_t_min_s,
                                        defaults.delta_t_max_s));
    } else {
      VerdictLine v;
      v.level = Level::kWarn;
      v.name = "Hall time offset delta_t";
      v.figure = "not identified: " + rep.delta_t_reason;
      v.rule = "warn when the recording does not determine delta_t (hall_model.yaml time_offset)";
      rep.verdict.push_back(v);
    }
    // The time base's fit figures (results::ReadHallModelYaml reads offset, rate and period).
    try {
      const YAML::Node tb = YAML::LoadFile(hall_yaml.string())["time_base"];
      rep.verdict.push_back(JudgeClock(
          Num(tb, "jitter_rms_us"), static_cast<int>(Num(tb, "edges_used")),
          static_cast<int>(Num(tb, "edges_missing")), static_cast<int>(Num(tb, "edges_rejected"))));
    } catch (const std::exception& e) {
      throw std::runtime_error(hall_yaml.string() + ": time_base: " + e.what());
    }

    if (rec && !planes.empty()) {
      HallAnalysis a = AnalyseHall(*rec, planes, model, dir);
      if (a.ok) {
        rep.have_noise_floor = true;
        rep.noise_floor_from_linear = a.floor_from_linear;
        for (int k = 0; k < 3; ++k) {
          rep.noise_floor[k] = a.floor[k];
          rep.reading_noise_uT[k] = a.reading_noise_uT[k];
        }
        if (model.test_rms) {
          rep.verdict.push_back(JudgeHallResidual(rep.test_rms, rep.noise_floor));
          if (a.floor_from_linear)
            rep.verdict.back().figure += " (floor through the linear model: the " + rep.hall_model +
                                         " model does not read the field)";
        }
        for (auto& c : a.charts) charts.push_back(std::move(c));
      } else {
        rep.skipped.push_back("Hall fit plots and noise floor: " + a.error);
      }
    }
    if (have_truth && fs::exists(res / "hall_poses.csv") && truth->HasPoseTrajectory()) {
      truth->CompareHallPoses(results::ReadHallPosesCsv(res / "hall_poses.csv"), &rep, &charts);
    } else {
      rep.skipped.push_back("Hall prediction vs truth: results/hall_poses.csv or truth missing");
    }
  } else {
    rep.skipped.push_back(
        "Table II figures: results/hall_model.yaml missing (Hall calibration "
        "did not run or failed)");
  }

  // Hall readings lost on the link and dropped by the recorder. Lost: the driver's count as the
  // journal has it (hall.<name>.readings_lost), else the gaps in the MCU time stamps.
  if (rec && (rec->hall_actual || rec->hall_background)) {
    long long expected = 0, lost = 0, dropped = -1;
    std::string by_recording;
    std::map<std::string, std::string> meta;
    if (fs::exists(dir / store::kSessionDbName)) {
      try {
        const store::SystemClock clock;
        const auto journal = store::SessionStore::Open(dir, clock, /*read_only=*/true);
        meta = journal->AllMeta();
      } catch (const std::exception& e) {
        rep.skipped.push_back(std::string("recorder drops: journal unreadable: ") + e.what());
      }
    }
    bool from_journal = false;
    for (const char* name : {"background", "actual"}) {
      const auto& hall_rec =
          std::string(name) == "actual" ? rec->hall_actual : rec->hall_background;
      if (!hall_rec) continue;
      long long gaps_expected = 0;
      const long long gaps = LostReadings(*hall_rec, &gaps_expected);
      const auto l = meta.find(std::string("hall.") + name + ".readings_lost");
      if (l != meta.end()) {
        const long long n = std::stoll(l->second);
        lost += n;
        expected += static_cast<long long>(hall_rec->readings.size()) + n;
        from_journal = true;
      } else {
        lost += gaps;
        expected += gaps_expected;
      }
      const auto d = meta.find(std::string("hall.") + name + ".readings_dropped");
      if (d != meta.end()) {
        dropped = std::max(0LL, dropped) + std::stoll(d->second);
        by_recording += std::string(by_recording.empty() ? "" : ", ") + name + " " + d->second;
      }
    }
    rep.verdict.push_back(JudgeReadingsLost(lost, dropped, expected));
    if (!by_recording.empty())
      rep.verdict.back().figure += " (recorder queue full: " + by_recording + ")";
    rep.verdict.back().figure += from_journal ? "; lost as the driver counted them"
                                              : "; lost from gaps in the MCU time stamps";
  }

  // ------------------------------------------------------------------------------ MARG
  const fs::path marg_yaml = res / "marg_calibration.yaml";
  if (fs::exists(marg_yaml)) {
    try {
      const YAML::Node v = YAML::LoadFile(marg_yaml.string())["validation"];
      const double c[3] = {Num(v, "mean_cost_raw"), Num(v, "mean_cost_compensated"),
                           Num(v, "mean_cost_aligned_compensated")};
      if (std::isfinite(c[0])) {
        Table t;
        t.id = "table-marg";
        t.title = "MARG attitude cost (validation recording)";
        t.header = {"calibration", "mean cost"};
        t.rows = {{"raw", Fmt("%.4g", c[0])},
                  {"compensated", Fmt("%.4g", c[1])},
                  {"aligned + compensated", Fmt("%.4g", c[2])}};
        rep.tables.push_back(t);
        Chart m;
        m.id = "plot-marg";
        m.title = "MARG attitude cost before / after calibration";
        m.x_label = "calibration";
        m.y_label = "mean cost (1)";
        m.categories = {"raw", "compensated", "aligned + compensated"};
        ChartSeries s = Series("mean cost", ChartSeries::Style::kBar, kGreen);
        s.y = {c[0], c[1], c[2]};
        m.series = {s};
        m.caption = "results/marg_calibration.yaml validation figures.";
        charts.push_back(m);
      } else {
        rep.skipped.push_back("MARG cost table: no validation costs in " + marg_yaml.string());
      }
    } catch (const std::exception& e) {
      throw std::runtime_error(marg_yaml.string() + ": " + e.what());
    }
  }

  // ------------------------------------------------------------------------------ text
  std::ostringstream t;
  t << "== Verdict: " << ToString(Overall(rep.verdict)) << " ==\n";
  for (const auto& v : rep.verdict)
    t << "  [" << ToString(v.level) << "] " << v.name << ": " << v.figure << "\n";
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
    t << "  delta_t estimated:                  "
      << (rep.delta_t_identified ? Fmt("%.4f ms", rep.delta_t_s * 1e3)
                                 : "not identified (" + rep.delta_t_reason + ")");
    if (have_truth && rep.delta_t_identified)
      t << Fmt(" (truth %.4f ms", rep.delta_t_truth_s * 1e3)
        << Fmt(", error %.4f ms)", (rep.delta_t_s - rep.delta_t_truth_s) * 1e3);
    t << "\n";
    if (rep.have_noise_floor)
      t << "  single-reading noise floor:         " << Fmt("%.4f deg / ", rep.noise_floor[0])
        << Fmt("%.4f deg / ", rep.noise_floor[1]) << Fmt("%.4f mm", rep.noise_floor[2])
        << Fmt(" (reading noise %.2f", rep.reading_noise_uT[0])
        << Fmt(" / %.2f", rep.reading_noise_uT[1]) << Fmt(" / %.2f uT", rep.reading_noise_uT[2])
        << (rep.noise_floor_from_linear ? "; through the linear model: the " + rep.hall_model +
                                              " model does not read the field)\n"
                                        : ")\n");
    if (rep.have_hall_vs_truth)
      t << "  Hall prediction vs true pose:       " << Fmt("%.4f deg / ", rep.hall_rms_vs_truth[0])
        << Fmt("%.4f deg / ", rep.hall_rms_vs_truth[1])
        << Fmt("%.4f mm RMS\n", rep.hall_rms_vs_truth[2]);
  } else {
    t << "  (skipped)\n";
  }
  t << "== Provenance ==\n  msmcal " << rep.provenance.msmcal_version << " ("
    << rep.provenance.git_commit << ", " << rep.provenance.build_type << ") on "
    << rep.provenance.host << "\n";
  for (const auto& s : rep.skipped) t << "SKIPPED: " << s << "\n";
  rep.text = t.str();

  // ------------------------------------------------------------------------------ HTML
  const Provenance& p = rep.provenance;
  std::ostringstream h;
  h << "<h1>msmcal calibration report</h1><p class=\"sub\">" << HtmlEscape(dir.string())
    << (p.start_utc.empty() ? "" : " &middot; " + HtmlEscape(p.start_utc)) << " &middot; msmcal "
    << HtmlEscape(p.msmcal_version) << " (" << HtmlEscape(p.git_commit) << ")</p>\n";
  h << RenderVerdict(rep.verdict);
  h << "<h2>Figures</h2>";
  for (const auto& tb : rep.tables) h << RenderTable(tb);
  h << "<h2>Plots</h2><div class=\"plots\">";
  for (const auto& c : charts) h << RenderChartPlace(c);
  h << "</div>\n";
  Table prov;
  prov.id = "table-provenance";
  prov.title = "Provenance";
  prov.header = {"what", "value"};
  prov.rows = {{"msmcal version", p.msmcal_version},
               {"git commit", p.git_commit},
               {"build type", p.build_type},
               {"command line", p.command_line},
               {"host", p.host},
               {"start (UTC)", p.start_utc.empty() ? "not recorded (no journal)" : p.start_utc},
               {"end (UTC)", p.end_utc.empty() ? "not recorded (no journal)" : p.end_utc}};
  for (const auto& [role, id] : p.instruments) prov.rows.push_back({"instrument " + role, id});
  if (p.instruments.empty())
    prov.rows.push_back({"instruments", "not recorded (no journal: not an acquired session)"});
  for (const auto& [file, hash] : p.config_sha256) prov.rows.push_back({"sha256 " + file, hash});
  if (!p.report_command_line.empty()) {
    prov.rows.push_back({"report written by", p.report_command_line});
    prov.rows.push_back({"report commit", p.report_git_commit});
    prov.rows.push_back({"report time (UTC)", p.report_time_utc});
  }
  prov.rows.push_back({"plotting library", PlottingLibraryDescription()});
  prov.caption = "Also in results/summary.json under \"provenance\".";
  h << "<h2>Provenance</h2>" << RenderTable(prov);
  if (!rep.skipped.empty()) {
    h << "<h2>Skipped</h2><ul id=\"skipped\">";
    for (const auto& s : rep.skipped) h << "<li>" << HtmlEscape(s) << "</li>";
    h << "</ul>";
  }
  if (!options.session_notes.empty()) {
    h << "<details><summary>Session log (" << options.session_notes.size()
      << " lines)</summary><pre>";
    for (const auto& n : options.session_notes) h << HtmlEscape(n) << "\n";
    h << "</pre></details>";
  }
  rep.html = RenderPage("msmcal calibration report: " + dir.filename().string(), h.str(), charts);
  return rep;
}

SessionReport WriteSessionReport(const fs::path& dir, const ReportOptions& options,
                                 const TruthSource& truth) {
  SessionReport r = BuildSessionReport(dir, options, truth);
  common::WriteFileAtomically(dir / "report.html", r.html);
  return r;
}

}  // namespace msmcal::report

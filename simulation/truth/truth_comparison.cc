#include "simulation/truth/truth_comparison.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/units.h"
#include "mocks/rig/truth_io.h"
#include "processing/geometry/mirror_frame.h"
#include "processing/geometry/plane_line.h"
#include "processing/solver/home_frame.h"

namespace msmcal::simulation {
namespace {

namespace fs = std::filesystem;
using report::Chart;
using report::ChartSeries;
using report::SessionReport;

ChartSeries Series(const std::string& name, ChartSeries::Style style, const char* colour) {
  ChartSeries s;
  s.name = name;
  s.style = style;
  s.colour = colour;
  return s;
}

double Rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? 0 : std::sqrt(s / v.size());
}

class SimTruthComparison : public report::TruthComparison {
 public:
  explicit SimTruthComparison(sim::SimTruth truth) : truth_(std::move(truth)) {}

  void CompareMirrorPlanes(const std::vector<dataset::MirrorPlaneRow>& planes,
                           SessionReport* report, std::vector<Chart>* charts) override {
    std::map<int, dataset::MirrorPlaneRow> by_j;
    for (const auto& r : truth_.mirror_planes) by_j[r.j] = r;
    // Poses are compared in one convention: the truth's {0} rebuilt as the solver builds it
    // (origin on the true neutral plane, placed by the true planes of the same triggers;
    // processing/solver/home_frame.h, docs/solver.md).
    std::vector<geometry::Plane> true_scan;
    for (const auto& p : planes)
      if (auto it = by_j.find(p.j); it != by_j.end())
        true_scan.push_back(it->second.plane_in_world);
    truth_frame_ = solver::ConventionalTruthFrame(truth_.world_from_mirror0, true_scan);
    std::vector<double> en, ea, eb, et;
    ChartSeries tru = Series("truth", ChartSeries::Style::kPoints, "#2ca02c");
    for (const auto& p : planes) {
      auto it = by_j.find(p.j);
      if (it == by_j.end()) continue;
      en.push_back(geometry::AngleBetween(p.plane_in_world.n, it->second.plane_in_world.n) * 180.0 /
                   M_PI);
      const geometry::MirrorPose t =
          geometry::PoseFromWorldPlane(*truth_frame_, it->second.plane_in_world);
      ea.push_back(p.alpha_deg - common::RadToDeg(t.alpha_rad));
      eb.push_back(p.beta_deg - common::RadToDeg(t.beta_rad));
      et.push_back(p.trans_mm - t.trans_mm);
      tru.x.push_back(common::RadToDeg(t.alpha_rad));
      tru.y.push_back(common::RadToDeg(t.beta_rad));
    }
    report->normal_rms_vs_truth_deg = Rms(en);
    report->alpha_rms_vs_truth_deg = Rms(ea);
    report->beta_rms_vs_truth_deg = Rms(eb);
    report->trans_rms_vs_truth_mm = Rms(et);
    for (auto& c : *charts)
      if (c.id == "plot-scan-pattern") c.series.push_back(tru);
    Chart dc;
    dc.id = "plot-true-dots";
    dc.title = "Scan pattern of laser dots on the world board (truth)";
    dc.x_label = "u (px)";
    dc.y_label = "v (px)";
    dc.y_reversed = true;
    ChartSeries dots =
        Series("true dot centres (step 2 scan frames)", ChartSeries::Style::kPoints, "#1f77b4");
    for (const auto& d : truth_.dots)
      if (d.j >= 0 && d.file.rfind("step2/", 0) == 0)
        dots.x.push_back(d.u_px), dots.y.push_back(d.v_px);
    dc.series = {dots};
    dc.caption = "The simulator's dot centres in the image (truth/dots.csv).";
    charts->push_back(dc);
  }

  double TrueDeltaT() const override { return truth_.hall.delta_t_s; }
  bool HasPoseTrajectory() const override { return !truth_.pose_trajectory.empty(); }

  void CompareHallPoses(const std::vector<results::HallPoseRow>& rows, SessionReport* report,
                        std::vector<Chart>* charts) override {
    const double period = truth_.hall.pattern_period_s > 0 ? truth_.hall.pattern_period_s
                                                           : truth_.pose_trajectory.back().t_s;
    // The true trajectory in the convention the Hall model was trained in (the solver's {0},
    // see above); without the solver's planes, in the simulator's own {0}.
    std::vector<sim::PoseSample> tr = truth_.pose_trajectory;
    if (truth_frame_) {
      for (auto& p : tr) {
        const geometry::Plane plane = geometry::WorldPlaneFromPose(
            truth_.world_from_mirror0,
            {common::DegToRad(p.alpha_deg), common::DegToRad(p.beta_deg), p.trans_mm});
        const geometry::MirrorPose q = geometry::PoseFromWorldPlane(*truth_frame_, plane);
        p.alpha_deg = common::RadToDeg(q.alpha_rad);
        p.beta_deg = common::RadToDeg(q.beta_rad);
        p.trans_mm = q.trans_mm;
      }
    }
    const double dt = tr.size() > 1 ? tr[1].t_s - tr[0].t_s : 1;
    std::vector<double> ea, eb, et;
    ChartSeries pa = Series("Hall prediction alpha", ChartSeries::Style::kPoints, "#d62728");
    ChartSeries ta = Series("true alpha", ChartSeries::Style::kLine, "#2ca02c");
    ChartSeries pb = Series("Hall prediction beta", ChartSeries::Style::kPoints, "#ff7f0e");
    ChartSeries tb = Series("true beta", ChartSeries::Style::kLine, "#1f77b4");
    for (const auto& p : tr)
      ta.x.push_back(p.t_s), ta.y.push_back(p.alpha_deg), tb.x.push_back(p.t_s),
          tb.y.push_back(p.beta_deg);
    for (size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      double ph = std::fmod(r.t_s, period);
      if (ph < 0) ph += period;
      const size_t k = std::min(tr.size() - 1, static_cast<size_t>(std::lround(ph / dt)));
      ea.push_back(r.alpha_deg - tr[k].alpha_deg);
      eb.push_back(r.beta_deg - tr[k].beta_deg);
      et.push_back(r.trans_mm - tr[k].trans_mm);
      if (i % 7 == 0 && pa.x.size() < 600) {
        pa.x.push_back(ph), pa.y.push_back(r.alpha_deg);
        pb.x.push_back(ph), pb.y.push_back(r.beta_deg);
      }
    }
    report->have_hall_vs_truth = !ea.empty();
    report->hall_rms_vs_truth[0] = Rms(ea);
    report->hall_rms_vs_truth[1] = Rms(eb);
    report->hall_rms_vs_truth[2] = Rms(et);
    Chart hc;
    hc.id = "plot-hall-vs-truth";
    hc.title = "Hall prediction against the true pose over one pattern period";
    hc.x_label = "pattern time (s)";
    hc.y_label = "angle (deg)";
    hc.series = {ta, tb, pa, pb};
    hc.caption = "results/hall_poses.csv (every 7th reading) against truth/pose_trajectory.csv.";
    charts->push_back(hc);
  }

 private:
  sim::SimTruth truth_;
  std::optional<geometry::Rigid3d> truth_frame_;  // truth's {0} in the solver's convention
};

}  // namespace

std::unique_ptr<report::TruthComparison> OpenSimTruth(const fs::path& dir) {
  if (!fs::exists(dir / "truth" / "mirror_planes.csv")) return nullptr;
  return std::make_unique<SimTruthComparison>(sim::ReadTruth(dir));
}

report::TruthSource SimTruthSource() { return OpenSimTruth; }

}  // namespace msmcal::simulation

#include "app/hall_cal_io.h"

#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "sessions/interchange/interchange_io.h"

namespace msmcal::app {

HallCalibrationSetup MakeHallCalibrationSetup(const dataset::Recording& rec,
                                              const std::vector<dataset::MirrorPlaneRow>& planes,
                                              const std::string& dir) {
  if (!rec.hall_actual) throw std::runtime_error(dir + "/hall/actual.csv: missing (the Hall recording made during the scan)");
  if (!rec.hall_background)
    throw std::runtime_error(dir + "/hall/background.csv: missing (the Hall recording with the mirror's top frame removed)");
  if (planes.empty()) throw std::runtime_error(dir + "/results/mirror_planes.csv: no mirror planes");
  HallCalibrationSetup s;
  s.actual = *rec.hall_actual;
  s.background = *rec.hall_background;
  s.pattern_period_s = rec.drive.pattern_period_s;
  s.fast_frequency_hz = rec.drive.fast.frequency_hz;
  s.slow_frequency_hz = rec.drive.slow.frequency_hz;
  for (const auto& p : planes) {
    hall::PoseSample ps;
    ps.t_s = p.t_s;
    ps.pose = Eigen::Vector3d(p.alpha_deg, p.beta_deg, p.trans_mm);
    s.poses.push_back(ps);
  }
  return s;
}

hall::HallCalibrationInput HallCalibrationSetup::Input() const {
  hall::HallCalibrationInput in;
  in.actual = &actual;
  in.background = &background;
  in.pattern_period_s = pattern_period_s;
  in.fast_frequency_hz = fast_frequency_hz;
  in.slow_frequency_hz = slow_frequency_hz;
  in.poses = poses;
  return in;
}

namespace {

YAML::Node Vec(const Eigen::Vector3d& v) {
  YAML::Node n(YAML::NodeType::Sequence);
  for (int k = 0; k < 3; ++k) n.push_back(interchange::FormatDouble(v[k]));
  n.SetStyle(YAML::EmitterStyle::Flow);
  return n;
}

YAML::Node Outputs(const Eigen::Vector3d& v) {
  YAML::Node n;
  n["alpha_deg"] = interchange::FormatDouble(v[0]);
  n["beta_deg"] = interchange::FormatDouble(v[1]);
  n["trans_mm"] = interchange::FormatDouble(v[2]);
  n.SetStyle(YAML::EmitterStyle::Flow);
  return n;
}

}  // namespace

std::string HallModelYaml(const hall::HallCalibrationResult& r, const hall::HallCalibrationOptions& o) {
  const hall::HallModel& m = r.final_fit.model;
  YAML::Node y;
  y["format"] = "msmcal-hall-model/1";
  y["model"] = hall::ToString(m.kind);
  y["delta_t_s"] = interchange::FormatDouble(m.delta_t_s);
  y["outputs"] = YAML::Load("[alpha_deg, beta_deg, trans_mm]");
  YAML::Node params;
  YAML::Node a(YAML::NodeType::Sequence);
  for (int i = 0; i < m.a.rows(); ++i) {
    YAML::Node row(YAML::NodeType::Sequence);
    for (int j = 0; j < m.a.cols(); ++j) row.push_back(interchange::FormatDouble(m.a(i, j)));
    row.SetStyle(YAML::EmitterStyle::Flow);
    a.push_back(row);
  }
  params["A"] = a;
  params["field_scale_uT"] = interchange::FormatDouble(m.field_scale_uT);
  params["sine_frequency_hz"] = Vec(m.sine_frequency_hz);
  params["sine_phase_rad"] = Vec(m.sine_phase_rad);
  y["parameters"] = params;
  const hall::ModelStats* best = nullptr;
  for (const auto& s : r.table)
    if (s.kind == m.kind) best = &s;
  y["train_rms"] = Outputs(r.final_fit.train_rms);
  if (best) {
    y["test_rms"] = Outputs(best->test_rms_mean);
    y["test_rms_std"] = Outputs(best->test_rms_std);
  }
  YAML::Node cmp(YAML::NodeType::Sequence);
  for (const auto& s : r.table) {
    YAML::Node e;
    e["model"] = hall::ToString(s.kind);
    e["test_rms"] = Outputs(s.test_rms_mean);
    e["test_rms_std"] = Outputs(s.test_rms_std);
    e["train_rms"] = Outputs(s.train_rms_mean);
    e["delta_t_s"] = interchange::FormatDouble(s.delta_t_mean_s);
    e["delta_t_std_s"] = interchange::FormatDouble(s.delta_t_std_s);
    cmp.push_back(e);
  }
  y["comparison"] = cmp;
  y["protocol"]["repetitions"] = o.repetitions;
  y["protocol"]["train_fraction"] = interchange::FormatDouble(o.train_fraction);
  y["protocol"]["seed"] = o.seed;
  const hall::TimeBase& tb = r.actual_time_base;
  y["time_base"]["offset_us"] = interchange::FormatDouble(tb.offset_us);
  y["time_base"]["rate_us_per_s"] = interchange::FormatDouble(tb.rate_us_per_s);
  y["time_base"]["pattern_period_s"] = interchange::FormatDouble(tb.pattern_period_s);
  y["time_base"]["jitter_rms_us"] = interchange::FormatDouble(tb.jitter_rms_us);
  y["time_base"]["edges_used"] = tb.edges_used;
  y["time_base"]["edges_missing"] = tb.edges_missing;
  y["time_base"]["edges_rejected"] = tb.edges_rejected;
  y["actual_mean_uT"] = Vec(r.foreground.actual.Mean());
  YAML::Node bins(YAML::NodeType::Sequence);
  for (const auto& b : r.foreground.background.bins()) bins.push_back(Vec(b));
  y["background_profile"]["period_s"] = interchange::FormatDouble(r.foreground.background.period_s());
  y["background_profile"]["bins_uT"] = bins;
  YAML::Emitter e;
  e << y;
  return std::string(e.c_str()) + "\n";
}

std::string FormatTableTwo(const hall::HallCalibrationResult& r, const hall::HallCalibrationOptions& o) {
  std::ostringstream s;
  char line[256];
  std::snprintf(line, sizeof line, "Table II (%d random %.0f:%.0f train/test splits, RMS +- std over splits)\n",
                o.repetitions, o.train_fraction * 10, (1 - o.train_fraction) * 10);
  s << line;
  std::snprintf(line, sizeof line, "%-10s %20s %20s %20s %14s\n", "model", "alpha (deg)", "beta (deg)", "trans (mm)", "dt (ms)");
  s << line;
  for (const auto& m : r.table) {
    std::snprintf(line, sizeof line, "%-10s %10.4f +- %6.4f %10.4f +- %6.4f %10.4f +- %6.4f %8.4f%s\n", hall::ToString(m.kind),
                  m.test_rms_mean[0], m.test_rms_std[0], m.test_rms_mean[1], m.test_rms_std[1], m.test_rms_mean[2],
                  m.test_rms_std[2], m.delta_t_mean_s * 1e3, m.kind == r.best ? "  <- best" : "");
    s << line;
  }
  for (const auto& skipped : r.skipped_models) s << "left out: " << skipped << "\n";
  s << "paper (sine): 0.083 +- 0.040 deg, 0.069 +- 0.040 deg, 0.10 +- 0.08 mm\n";
  return s.str();
}

namespace {

[[noreturn]] void Fail(const std::string& file, const std::string& field, const std::string& what) {
  throw std::runtime_error(file + ": field '" + field + "': " + what);
}

YAML::Node Need(const YAML::Node& n, const std::string& key, const std::string& file, const std::string& path) {
  if (!n[key]) Fail(file, path + key, "missing");
  return n[key];
}

double Num(const YAML::Node& n, const std::string& file, const std::string& field) {
  try {
    return n.as<double>();
  } catch (const YAML::Exception&) {
    Fail(file, field, "expected a number (line " + std::to_string(n.Mark().line + 1) + ")");
  }
}

Eigen::Vector3d Vec3(const YAML::Node& n, const std::string& file, const std::string& field) {
  if (!n.IsSequence() || n.size() != 3) Fail(file, field, "expected a list of 3 numbers");
  return {Num(n[0], file, field), Num(n[1], file, field), Num(n[2], file, field)};
}

}  // namespace

LoadedHallModel ReadHallModelYaml(const std::string& file) {
  YAML::Node y;
  try {
    y = YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(file + ": " + e.what());
  }
  const std::string format = Need(y, "format", file, "").as<std::string>();
  if (format != "msmcal-hall-model/1") Fail(file, "format", "expected msmcal-hall-model/1, got '" + format + "'");
  LoadedHallModel l;
  const std::string kind = Need(y, "model", file, "").as<std::string>();
  if (!hall::ParseHallModelKind(kind, &l.model.kind)) Fail(file, "model", "unknown model '" + kind + "'");
  l.model.delta_t_s = Num(Need(y, "delta_t_s", file, ""), file, "delta_t_s");
  const YAML::Node p = Need(y, "parameters", file, "");
  const YAML::Node a = Need(p, "A", file, "parameters.");
  const int f = l.model.FeatureCount();
  if (!a.IsSequence() || a.size() != 3) Fail(file, "parameters.A", "expected 3 rows");
  l.model.a.resize(3, f);
  for (int i = 0; i < 3; ++i) {
    if (!a[i].IsSequence() || static_cast<int>(a[i].size()) != f)
      Fail(file, "parameters.A", "row " + std::to_string(i) + " must have " + std::to_string(f) + " values for model " + kind);
    for (int j = 0; j < f; ++j) l.model.a(i, j) = Num(a[i][j], file, "parameters.A");
  }
  l.model.field_scale_uT = Num(Need(p, "field_scale_uT", file, "parameters."), file, "parameters.field_scale_uT");
  l.model.sine_frequency_hz = Vec3(Need(p, "sine_frequency_hz", file, "parameters."), file, "parameters.sine_frequency_hz");
  l.model.sine_phase_rad = Vec3(Need(p, "sine_phase_rad", file, "parameters."), file, "parameters.sine_phase_rad");
  const YAML::Node tb = Need(y, "time_base", file, "");
  l.time_base.offset_us = Num(Need(tb, "offset_us", file, "time_base."), file, "time_base.offset_us");
  l.time_base.rate_us_per_s = Num(Need(tb, "rate_us_per_s", file, "time_base."), file, "time_base.rate_us_per_s");
  l.time_base.pattern_period_s = Num(Need(tb, "pattern_period_s", file, "time_base."), file, "time_base.pattern_period_s");
  l.actual_mean_uT = Vec3(Need(y, "actual_mean_uT", file, ""), file, "actual_mean_uT");
  const YAML::Node bp = Need(y, "background_profile", file, "");
  const double period = Num(Need(bp, "period_s", file, "background_profile."), file, "background_profile.period_s");
  const YAML::Node bins = Need(bp, "bins_uT", file, "background_profile.");
  std::vector<Eigen::Vector3d> b;
  for (const auto& n : bins) b.push_back(Vec3(n, file, "background_profile.bins_uT"));
  try {
    l.background = hall::PhaseProfile::FromBins(period, std::move(b));
  } catch (const std::invalid_argument& e) {
    Fail(file, "background_profile", e.what());
  }
  return l;
}

}  // namespace msmcal::app

#include "processing/hall/hall_model.h"

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace msmcal::hall {

const char* ToString(HallModelKind kind) {
  switch (kind) {
    case HallModelKind::kLinear:
      return "linear";
    case HallModelKind::kSine:
      return "sine";
    case HallModelKind::kQuadratic:
      return "quadratic";
    case HallModelKind::kCubic:
      return "cubic";
  }
  return "?";
}

bool ParseHallModelKind(const std::string& text, HallModelKind* kind) {
  for (HallModelKind k : {HallModelKind::kLinear, HallModelKind::kSine, HallModelKind::kQuadratic,
                          HallModelKind::kCubic})
    if (text == ToString(k)) {
      *kind = k;
      return true;
    }
  return false;
}

int HallModel::FeatureCount() const {
  switch (kind) {
    case HallModelKind::kLinear:
    case HallModelKind::kSine:
      return 4;
    case HallModelKind::kQuadratic:
      return 10;
    case HallModelKind::kCubic:
      return 20;
  }
  return 0;
}

void HallModel::Features(const Eigen::Vector3d& b, double tau, double* out) const {
  switch (kind) {
    case HallModelKind::kLinear:
      out[0] = b.x();
      out[1] = b.y();
      out[2] = b.z();
      out[3] = 1.0;
      return;
    case HallModelKind::kSine:
      for (int k = 0; k < 3; ++k)
        out[k] = std::sin(2 * M_PI * sine_frequency_hz[k] * tau + sine_phase_rad[k]);
      out[3] = 1.0;
      return;
    case HallModelKind::kQuadratic:
    case HallModelKind::kCubic: {
      const Eigen::Vector3d s = b / field_scale_uT;
      out[0] = 1.0;
      out[1] = s.x();
      out[2] = s.y();
      out[3] = s.z();
      out[4] = s.x() * s.x();
      out[5] = s.y() * s.y();
      out[6] = s.z() * s.z();
      out[7] = s.x() * s.y();
      out[8] = s.x() * s.z();
      out[9] = s.y() * s.z();
      if (kind == HallModelKind::kCubic) {
        int k = 10;
        for (int i = 0; i < 3; ++i)
          for (int j = i; j < 3; ++j)
            for (int l = j; l < 3; ++l) out[k++] = s[i] * s[j] * s[l];
      }
      return;
    }
  }
}

Eigen::Vector3d HallModel::Predict(const Eigen::Vector3d& b, double tau) const {
  double f[20];
  Features(b, tau, f);
  const int n = FeatureCount();
  return a.leftCols(n) * Eigen::Map<const Eigen::VectorXd>(f, n);
}

std::string HallFitOptions::Validate(HallModelKind kind) const {
  std::ostringstream s;
  if (!(delta_t_max_s > delta_t_min_s))
    s << "delta_t window must satisfy max > min, got [" << delta_t_min_s << ", " << delta_t_max_s
      << "]";
  else if (!(grid_step_s > 0))
    s << "grid_step_s must be > 0, got " << grid_step_s;
  else if (!(tolerance_s > 0))
    s << "tolerance_s must be > 0, got " << tolerance_s;
  else if (kind == HallModelKind::kSine &&
           !(fast_frequency_hz > 0 && slow_frequency_hz > 0 && pattern_period_s > 0))
    s << "sine model needs fast_frequency_hz, slow_frequency_hz and pattern_period_s > 0";
  return s.str();
}

namespace {

// Solves A for fixed dt; returns the cost.
double SolveForDelta(HallModel* model, const std::vector<PoseSample>& samples,
                     const FieldFunction& fg) {
  const int n = model->FeatureCount();
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(n, n);
  Eigen::MatrixXd aty = Eigen::MatrixXd::Zero(n, 3);
  std::vector<Eigen::VectorXd> feats;
  feats.reserve(samples.size());
  double f[20];
  for (const auto& s : samples) {
    const double tau = s.t_s + model->delta_t_s;
    model->Features(fg(tau), tau, f);
    Eigen::Map<const Eigen::VectorXd> x(f, n);
    ata.noalias() += x * x.transpose();
    aty.noalias() += x * s.pose.transpose();
    feats.emplace_back(x);
  }
  // Tiny ridge for rank safety (e.g. a Hall axis with no signal); relative to the diagonal.
  const double ridge = 1e-12 * ata.diagonal().cwiseAbs().maxCoeff();
  ata.diagonal().array() += ridge;
  model->a = ata.ldlt().solve(aty).transpose();
  double cost = 0;
  for (size_t i = 0; i < samples.size(); ++i)
    cost += (model->a * feats[i] - samples[i].pose).squaredNorm();
  return cost;
}

// Dominant drive frequency and phase of each axis of the foreground over one pattern period.
void MeasureSinePhases(const FieldFunction& fg, const HallFitOptions& o, HallModel* model) {
  const int n = 4096;
  for (int k = 0; k < 3; ++k) {
    double best_amp = -1;
    for (double f : {o.fast_frequency_hz, o.slow_frequency_hz}) {
      double s = 0, c = 0;
      for (int i = 0; i < n; ++i) {
        const double t = o.pattern_period_s * i / n;
        const double v = fg(t)[k];
        s += v * std::sin(2 * M_PI * f * t);
        c += v * std::cos(2 * M_PI * f * t);
      }
      const double amp = std::hypot(s, c);
      if (amp > best_amp) {
        best_amp = amp;
        model->sine_frequency_hz[k] = f;
        // v ~ R sin(2 pi f t + phi) = R (sin cos(phi) + cos sin(phi)): s ~ cos(phi), c ~ sin(phi).
        model->sine_phase_rad[k] = std::atan2(c, s);
      }
    }
  }
}

// The model of `kind` with what does not depend on dt set up (field scale, sine phases).
HallModel SetUpModel(HallModelKind kind, const std::vector<PoseSample>& samples,
                     const FieldFunction& fg, const HallFitOptions& o) {
  if (const std::string e = o.Validate(kind); !e.empty())
    throw std::invalid_argument("HallFitOptions: " + e);
  HallModel model;
  model.kind = kind;
  if (static_cast<int>(samples.size()) <= model.FeatureCount())
    throw std::invalid_argument(std::string("FitHallModel: the ") + ToString(kind) +
                                " model needs more than " + std::to_string(model.FeatureCount()) +
                                " poses, got " + std::to_string(samples.size()));
  if (kind == HallModelKind::kQuadratic || kind == HallModelKind::kCubic) {
    double ss = 0;
    for (const auto& s : samples) ss += fg(s.t_s).squaredNorm();
    model.field_scale_uT = std::max(1e-9, std::sqrt(ss / samples.size() / 3));
  }
  if (kind == HallModelKind::kSine) MeasureSinePhases(fg, o, &model);
  return model;
}

// The search grid: delta_t_min_s + k grid_step_s up to delta_t_max_s (within 1e-15 s).
int GridPoints(const HallFitOptions& o) {
  return static_cast<int>(std::floor((o.delta_t_max_s - o.delta_t_min_s + 1e-15) / o.grid_step_s)) +
         1;
}

}  // namespace

DeltaTProfile ProfileDeltaT(HallModelKind kind, const std::vector<PoseSample>& samples,
                            const FieldFunction& fg, const HallFitOptions& o) {
  HallModel model = SetUpModel(kind, samples, fg, o);
  DeltaTProfile p;
  p.kind = kind;
  p.residual_dof = 3 * (static_cast<int>(samples.size()) - model.FeatureCount());
  const int n = GridPoints(o);
  p.dt_s.reserve(n);
  p.cost.reserve(n);
  for (int k = 0; k < n; ++k) {
    model.delta_t_s = o.delta_t_min_s + k * o.grid_step_s;
    p.dt_s.push_back(model.delta_t_s);
    p.cost.push_back(SolveForDelta(&model, samples, fg));
  }
  return p;
}

HallFitResult FitHallModel(HallModelKind kind, const std::vector<PoseSample>& samples,
                           const FieldFunction& fg, const HallFitOptions& o) {
  HallModel model = SetUpModel(kind, samples, fg, o);
  auto cost_at = [&](double dt) {
    model.delta_t_s = dt;
    return SolveForDelta(&model, samples, fg);
  };
  // Global scan.
  double best_dt = o.delta_t_min_s, best_cost = std::numeric_limits<double>::infinity();
  for (int k = 0, n = GridPoints(o); k < n; ++k) {
    const double dt = o.delta_t_min_s + k * o.grid_step_s;
    const double c = cost_at(dt);
    if (c < best_cost) {
      best_cost = c;
      best_dt = dt;
    }
  }
  // Golden-section refinement in the bracket around the best grid point.
  double lo = std::max(o.delta_t_min_s, best_dt - o.grid_step_s);
  double hi = std::min(o.delta_t_max_s, best_dt + o.grid_step_s);
  const double g = (std::sqrt(5.0) - 1) / 2;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = cost_at(x1), f2 = cost_at(x2);
  while (hi - lo > o.tolerance_s) {
    if (f1 < f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = cost_at(x1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = cost_at(x2);
    }
  }
  const double dt = 0.5 * (lo + hi);
  HallFitResult r;
  r.cost = cost_at(dt);
  if (best_cost < r.cost) r.cost = cost_at(best_dt);
  r.model = model;
  r.samples = static_cast<int>(samples.size());
  r.train_rms = EvaluateRms(r.model, samples, fg);
  return r;
}

Eigen::Vector3d EvaluateRms(const HallModel& model, const std::vector<PoseSample>& samples,
                            const FieldFunction& fg) {
  Eigen::Vector3d ss = Eigen::Vector3d::Zero();
  for (const auto& s : samples) {
    const double tau = s.t_s + model.delta_t_s;
    const Eigen::Vector3d e = model.Predict(fg(tau), tau) - s.pose;
    ss += e.cwiseProduct(e);
  }
  return (ss / std::max<size_t>(1, samples.size())).cwiseSqrt();
}

}  // namespace msmcal::hall

#include "processing/hall/phase_profile.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace msmcal::hall {

std::string PhaseProfileOptions::Validate() const {
  std::ostringstream s;
  if (!(min_bin_width_s > 0)) s << "min_bin_width_s must be > 0, got " << min_bin_width_s;
  else if (!(min_occupancy > 0 && min_occupancy <= 1)) s << "min_occupancy must be in (0, 1], got " << min_occupancy;
  else if (!(readings_per_bin >= 1)) s << "readings_per_bin must be >= 1, got " << readings_per_bin;
  else if (max_harmonic < 0) s << "max_harmonic must be >= 0, got " << max_harmonic;
  else if (!(sample_period_s >= 0)) s << "sample_period_s must be >= 0, got " << sample_period_s;
  return s.str();
}

namespace {

double Wrap(double t, double period) {
  double p = std::fmod(t, period);
  if (p < 0) p += period;
  return p;
}

}  // namespace

double MedianSpacing(const std::vector<double>& t) {
  std::vector<double> d;
  d.reserve(t.size());
  for (size_t i = 1; i < t.size(); ++i)
    if (t[i] > t[i - 1]) d.push_back(t[i] - t[i - 1]);
  if (d.empty()) return 0;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

PhaseProfile PhaseProfile::BuildFourier(const std::vector<double>& t_s, const std::vector<double>& phase,
                                        const std::vector<Eigen::Vector3d>& values, double period_s,
                                        const PhaseProfileOptions& options) {
  int harmonics = options.max_harmonic;
  if (harmonics == 0) {
    const double spacing = options.sample_period_s > 0 ? options.sample_period_s : MedianSpacing(t_s);
    if (!(spacing > 0)) throw std::invalid_argument("PhaseProfile: cannot measure the sample rate (readings not in time order?)");
    // Strictly below Nyquist: a harmonic at exactly f_s / 2 is not observable.
    harmonics = std::max(1, static_cast<int>(std::ceil(0.5 / spacing * period_s)) - 1);
  }
  // Fine bins: 8 per period of the highest harmonic, at least as fine as the readings.
  const int m = std::max(4 * harmonics + 4, 8 * harmonics);
  std::vector<Eigen::Vector3d> sum(m, Eigen::Vector3d::Zero());
  std::vector<double> phase_sum(m, 0.0);
  std::vector<int> count(m, 0);
  for (size_t i = 0; i < phase.size(); ++i) {
    const int b = std::min(m - 1, static_cast<int>(phase[i] / period_s * m));
    sum[b] += values[i];
    phase_sum[b] += phase[i];
    ++count[b];
  }
  const int p = 2 * harmonics + 1;
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(p, p);
  Eigen::MatrixXd atb = Eigen::MatrixXd::Zero(p, 3);
  Eigen::VectorXd row(p);
  auto basis = [&](double theta, Eigen::VectorXd* r) {
    (*r)(0) = 1.0;
    for (int n = 1; n <= harmonics; ++n) {
      (*r)(2 * n - 1) = std::cos(n * theta);
      (*r)(2 * n) = std::sin(n * theta);
    }
  };
  int occupied = 0;
  for (int b = 0; b < m; ++b) {
    if (count[b] == 0) continue;
    ++occupied;
    // The bin's mean phase, not its centre: readings cluster where the MCU's grid puts them.
    basis(2 * M_PI * phase_sum[b] / count[b] / period_s, &row);
    const double w = count[b];
    ata.selfadjointView<Eigen::Lower>().rankUpdate(row, w);
    atb.noalias() += w * row * (sum[b] / count[b]).transpose();
  }
  if (occupied < p / 2)
    throw std::invalid_argument("PhaseProfile: readings cover only " + std::to_string(occupied) + " of " + std::to_string(m) +
                                " phase bins; record longer");
  ata.triangularView<Eigen::Upper>() = ata.transpose();
  // A tiny ridge keeps harmonics that the covered phases cannot pin down bounded.
  ata.diagonal().array() += 1e-6 * ata.diagonal().mean();
  const Eigen::MatrixXd coef = ata.ldlt().solve(atb);
  const int out_bins = 2 * m;
  std::vector<Eigen::Vector3d> bins(out_bins);
  for (int b = 0; b < out_bins; ++b) {
    basis(2 * M_PI * (b + 0.5) / out_bins, &row);
    bins[b] = coef.transpose() * row;
  }
  return FromBins(period_s, std::move(bins));
}

PhaseProfile PhaseProfile::FromBins(double period_s, std::vector<Eigen::Vector3d> bins) {
  if (!(period_s > 0) || bins.size() < 4) throw std::invalid_argument("PhaseProfile: needs period > 0 and >= 4 bins");
  PhaseProfile p;
  p.period_s_ = period_s;
  p.bins_ = std::move(bins);
  p.mean_.setZero();
  for (const auto& b : p.bins_) p.mean_ += b;
  p.mean_ /= static_cast<double>(p.bins_.size());
  return p;
}

PhaseProfile PhaseProfile::Build(const std::vector<double>& t_s, const std::vector<Eigen::Vector3d>& values,
                                 double period_s, const PhaseProfileOptions& options) {
  if (const std::string e = options.Validate(); !e.empty()) throw std::invalid_argument("PhaseProfileOptions: " + e);
  if (t_s.size() != values.size()) throw std::invalid_argument("PhaseProfile: times and values differ in length");
  if (!(period_s > 0)) throw std::invalid_argument("PhaseProfile: period must be > 0");
  if (t_s.size() < 16) throw std::invalid_argument("PhaseProfile: needs at least 16 readings, got " + std::to_string(t_s.size()));
  std::vector<double> phase(t_s.size());
  for (size_t i = 0; i < t_s.size(); ++i) phase[i] = Wrap(t_s[i], period_s);
  if (options.method == PhaseProfileOptions::Method::kFourier) return BuildFourier(t_s, phase, values, period_s, options);
  const int max_bins = std::max(4, static_cast<int>(std::floor(period_s / options.min_bin_width_s)));
  int m = std::clamp(static_cast<int>(t_s.size() / options.readings_per_bin), 4, max_bins);
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> count;
  for (;;) {
    sum.assign(m, Eigen::Vector3d::Zero());
    count.assign(m, 0);
    for (size_t i = 0; i < phase.size(); ++i) {
      const int b = std::min(m - 1, static_cast<int>(phase[i] / period_s * m));
      sum[b] += values[i];
      ++count[b];
    }
    const int occupied = static_cast<int>(std::count_if(count.begin(), count.end(), [](int c) { return c > 0; }));
    if (occupied >= options.min_occupancy * m || m <= 4) break;
    m = std::max(4, static_cast<int>(m * 0.7));
  }
  std::vector<Eigen::Vector3d> bins(m);
  std::vector<int> filled;
  for (int b = 0; b < m; ++b)
    if (count[b] > 0) {
      bins[b] = sum[b] / count[b];
      filled.push_back(b);
    }
  if (filled.empty()) throw std::invalid_argument("PhaseProfile: no readings");
  // Fill empty bins linearly between the neighbouring filled bins (periodically).
  for (size_t f = 0; f < filled.size(); ++f) {
    const int a = filled[f];
    const int b = filled[(f + 1) % filled.size()];
    const int gap = (b - a + m) % m;
    for (int k = 1; k < gap; ++k) {
      const double w = static_cast<double>(k) / gap;
      bins[(a + k) % m] = (1 - w) * bins[a] + w * bins[b];
    }
  }
  return FromBins(period_s, std::move(bins));
}

Eigen::Vector3d PhaseProfile::At(double t_s) const {
  const int m = static_cast<int>(bins_.size());
  double x = t_s / period_s_;
  x -= std::floor(x);  // phase in [0, 1): cheaper than fmod on the predictor's hot path
  const double u = x * m - 0.5;
  const double fl = std::floor(u);
  const double f = u - fl;
  int i1 = static_cast<int>(fl);
  i1 = ((i1 % m) + m) % m;
  const int i0 = (i1 + m - 1) % m, i2 = (i1 + 1) % m, i3 = (i1 + 2) % m;
  const Eigen::Vector3d& p0 = bins_[i0];
  const Eigen::Vector3d& p1 = bins_[i1];
  const Eigen::Vector3d& p2 = bins_[i2];
  const Eigen::Vector3d& p3 = bins_[i3];
  // Catmull-Rom: C1, interpolates the bin centres.
  const double f2 = f * f, f3 = f2 * f;
  return 0.5 * ((2 * p1) + (-p0 + p2) * f + (2 * p0 - 5 * p1 + 4 * p2 - p3) * f2 + (-p0 + 3 * p1 - 3 * p2 + p3) * f3);
}

}  // namespace msmcal::hall

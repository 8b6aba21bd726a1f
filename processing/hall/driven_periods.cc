#include "processing/hall/driven_periods.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <sstream>
#include <stdexcept>

#include "processing/hall/phase_profile.h"

namespace msmcal::hall {

std::string DrivenPeriodOptions::Validate() const {
  std::ostringstream s;
  if (!(min_amplitude_ratio > 0 && min_amplitude_ratio <= 1))
    s << "min_amplitude_ratio must be in (0, 1], got " << min_amplitude_ratio;
  else if (margin_periods < 0)
    s << "margin_periods must be >= 0, got " << margin_periods;
  else if (!(min_coverage > 0 && min_coverage <= 1))
    s << "min_coverage must be in (0, 1], got " << min_coverage;
  return s.str();
}

namespace {

struct Period {
  size_t first = 0, end = 0;  // readings [first, end)
  bool whole = false;
  double amplitude[2] = {0, 0};  // fast, slow
  bool driven = false;
  bool used = false;
};

// Amplitude of the mean-free readings [p.first, p.end) at frequency f: the norm over the axes
// of 2/n |sum (b - mean) e^{-i 2 pi f t}|.
double Amplitude(const std::vector<double>& t, const std::vector<Eigen::Vector3d>& b,
                 const Period& p, double f) {
  const double n = static_cast<double>(p.end - p.first);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t i = p.first; i < p.end; ++i) mean += b[i];
  mean /= n;
  std::complex<double> s[3];
  for (size_t i = p.first; i < p.end; ++i) {
    const std::complex<double> e = std::polar(1.0, -2 * M_PI * f * t[i]);
    for (int k = 0; k < 3; ++k) s[k] += (b[i][k] - mean[k]) * e;
  }
  return 2 / n * std::sqrt(std::norm(s[0]) + std::norm(s[1]) + std::norm(s[2]));
}

double Percentile90(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t k = static_cast<size_t>(std::floor(0.9 * static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace

DrivenPeriods SelectDrivenPeriods(const std::vector<double>& t,
                                  const std::vector<Eigen::Vector3d>& b, double period_s,
                                  double fast_hz, double slow_hz, const DrivenPeriodOptions& o) {
  if (const std::string e = o.Validate(); !e.empty())
    throw std::invalid_argument("DrivenPeriodOptions: " + e);
  if (t.size() != b.size())
    throw std::invalid_argument("SelectDrivenPeriods: times and fields differ in length");
  if (!(period_s > 0)) throw std::invalid_argument("SelectDrivenPeriods: period must be > 0");
  DrivenPeriods r;
  r.use.assign(t.size(), !o.enabled);
  if (!o.enabled) {
    r.readings_used = t.size();
    return r;
  }
  const double spacing = MedianSpacing(t);
  if (!(spacing > 0)) return r;
  const double per_period = period_s / spacing;
  std::vector<Period> periods;
  for (size_t i = 0; i < t.size();) {
    Period p;
    p.first = i;
    const double k = std::floor(t[i] / period_s);
    while (i < t.size() && std::floor(t[i] / period_s) == k) ++i;
    p.end = i;
    p.whole = static_cast<double>(p.end - p.first) >= o.min_coverage * per_period;
    periods.push_back(p);
  }
  const double freq[2] = {fast_hz, slow_hz};
  std::vector<double> amps[2];
  for (auto& p : periods) {
    if (!p.whole) continue;
    ++r.periods;
    for (int f = 0; f < 2; ++f) {
      if (!(freq[f] > 0)) continue;
      p.amplitude[f] = Amplitude(t, b, p, freq[f]);
      amps[f].push_back(p.amplitude[f]);
    }
  }
  const double ref[2] = {Percentile90(amps[0]), Percentile90(amps[1])};
  for (auto& p : periods) {
    p.driven = p.whole;
    for (int f = 0; f < 2; ++f)
      if (freq[f] > 0 && p.amplitude[f] < o.min_amplitude_ratio * ref[f]) p.driven = false;
    if (p.whole && !p.driven) ++r.not_driven;
  }
  const int n = static_cast<int>(periods.size());
  for (int k = 0; k < n; ++k) {
    if (!periods[k].driven) continue;
    bool near_undriven = false;
    for (int d = -o.margin_periods; d <= o.margin_periods && !near_undriven; ++d) {
      const int j = k + d;
      // The recording's partial first and last periods are no drive change.
      if (j >= 0 && j < n && periods[j].whole && !periods[j].driven) near_undriven = true;
    }
    if (near_undriven) {
      ++r.margin;
      continue;
    }
    ++r.driven;
    periods[k].used = true;
  }
  // A partial period (the recording's ends, a gap) is used when the whole periods next to it are.
  for (int k = 0; k < n; ++k) {
    if (periods[k].whole) continue;
    bool any = false, all = true;
    for (int j : {k - 1, k + 1}) {
      if (j < 0 || j >= n || !periods[j].whole) continue;
      any = true;
      all = all && periods[j].used;
    }
    periods[k].used = any && all;
  }
  for (const auto& p : periods) {
    if (!p.used) continue;
    for (size_t i = p.first; i < p.end; ++i) r.use[i] = true;
    r.readings_used += p.end - p.first;
  }
  return r;
}

}  // namespace msmcal::hall

#include "processing/hall/time_base.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace msmcal::hall {

std::string TimeBaseOptions::Validate() const {
  std::ostringstream s;
  if (!(max_rate_error_ppm > 0))
    s << "max_rate_error_ppm must be > 0, got " << max_rate_error_ppm;
  else if (!(max_phase_error > 0 && max_phase_error < 0.5))
    s << "max_phase_error must be in (0, 0.5), got " << max_phase_error;
  return s.str();
}

namespace {

struct LineFit {
  double a = 0, b = 0;  // tau = a + b k
};

LineFit FitIndexLine(const std::vector<double>& k, const std::vector<double>& tau,
                     const std::vector<char>& keep) {
  double n = 0, sk = 0, st = 0;
  for (size_t i = 0; i < k.size(); ++i)
    if (keep[i]) {
      n += 1;
      sk += k[i];
      st += tau[i];
    }
  const double mk = sk / n, mt = st / n;
  double skk = 0, skt = 0;
  for (size_t i = 0; i < k.size(); ++i)
    if (keep[i]) {
      skk += (k[i] - mk) * (k[i] - mk);
      skt += (k[i] - mk) * (tau[i] - mt);
    }
  LineFit f;
  f.b = skk > 0 ? skt / skk : 0;
  f.a = mt - f.b * mk;
  return f;
}

}  // namespace

TimeBase FitTimeBase(const std::vector<double>& edges, double period_s,
                     const TimeBaseOptions& options) {
  if (const std::string e = options.Validate(); !e.empty())
    throw std::invalid_argument("TimeBaseOptions: " + e);
  if (!(period_s > 0)) throw std::invalid_argument("FitTimeBase: pattern period must be > 0");
  if (edges.size() < 2)
    throw std::invalid_argument("FitTimeBase: needs at least 2 clock edges, got " +
                                std::to_string(edges.size()));
  const double nominal_us = period_s * 1e6;
  // Period in MCU time: the median of the edge differences that are near the nominal period
  // (a missing edge gives 2T, a spurious one a fraction of T).
  std::vector<double> diffs;
  for (size_t i = 1; i < edges.size(); ++i) {
    const double d = static_cast<double>(edges[i] - edges[i - 1]);
    if (std::abs(d / nominal_us - 1.0) < options.max_rate_error_ppm * 1e-6 + 0.01)
      diffs.push_back(d);
  }
  double period_us = nominal_us;
  if (!diffs.empty()) {
    std::nth_element(diffs.begin(), diffs.begin() + diffs.size() / 2, diffs.end());
    period_us = diffs[diffs.size() / 2];
  }
  // Index every edge relative to an anchor: the median-time edge is robust against a spurious
  // first edge. Edges off the grid by more than max_phase_error are rejected.
  const size_t anchor = edges.size() / 2;
  std::vector<double> k(edges.size()), tau(edges.size());
  std::vector<char> keep(edges.size(), 1);
  for (size_t i = 0; i < edges.size(); ++i) {
    const double frac = static_cast<double>(edges[i] - edges[anchor]) / period_us;
    k[i] = std::round(frac);
    tau[i] = static_cast<double>(edges[i] - edges[anchor]);
    if (std::abs(frac - k[i]) > options.max_phase_error) keep[i] = 0;
  }
  // Duplicate indices (a spurious edge near a real one): keep the one closer to the grid.
  for (size_t i = 1; i < edges.size(); ++i) {
    if (keep[i] && keep[i - 1] && k[i] == k[i - 1]) {
      const double ei = std::abs(tau[i] / period_us - k[i]),
                   ep = std::abs(tau[i - 1] / period_us - k[i - 1]);
      keep[ei < ep ? i - 1 : i] = 0;
    }
  }
  // Least squares with two rounds of 5-sigma (robust scale) rejection.
  LineFit fit = FitIndexLine(k, tau, keep);
  for (int round = 0; round < 2; ++round) {
    std::vector<double> abs_res;
    for (size_t i = 0; i < k.size(); ++i)
      if (keep[i]) abs_res.push_back(std::abs(tau[i] - fit.a - fit.b * k[i]));
    if (abs_res.size() < 3) break;
    std::nth_element(abs_res.begin(), abs_res.begin() + abs_res.size() / 2, abs_res.end());
    const double scale = std::max(1.4826 * abs_res[abs_res.size() / 2], 1.0);  // >= 1 us quantum
    for (size_t i = 0; i < k.size(); ++i)
      if (keep[i] && std::abs(tau[i] - fit.a - fit.b * k[i]) > 5 * scale) keep[i] = 0;
    fit = FitIndexLine(k, tau, keep);
  }
  TimeBase tb;
  tb.pattern_period_s = period_s;
  double k_min = 1e300, k_max = -1e300, ss = 0;
  for (size_t i = 0; i < k.size(); ++i) {
    if (!keep[i]) {
      ++tb.edges_rejected;
      continue;
    }
    ++tb.edges_used;
    k_min = std::min(k_min, k[i]);
    k_max = std::max(k_max, k[i]);
    const double r = tau[i] - fit.a - fit.b * k[i];
    ss += r * r;
  }
  if (tb.edges_rejected > tb.edges_used) {
    std::ostringstream s;
    s << "FitTimeBase: " << tb.edges_rejected << " of " << edges.size()
      << " clock edges do not fall on a grid of the pattern period " << period_s << " s";
    throw std::invalid_argument(s.str());
  }
  if (tb.edges_used < 2)
    throw std::invalid_argument("FitTimeBase: fewer than 2 clock edges on a common grid");
  tb.edges_missing = static_cast<int>(k_max - k_min + 1) - tb.edges_used;
  tb.jitter_rms_us = std::sqrt(ss / tb.edges_used);
  tb.rate_us_per_s = fit.b / period_s;
  if (std::abs(tb.RateErrorPpm()) > options.max_rate_error_ppm) {
    std::ostringstream s;
    s << "FitTimeBase: clock edges imply a rate error of " << tb.RateErrorPpm() << " ppm (limit "
      << options.max_rate_error_ppm << " ppm): is the pattern period " << period_s << " s right?";
    throw std::invalid_argument(s.str());
  }
  // Generator time 0 = the first kept edge's pattern start.
  tb.offset_us = static_cast<double>(edges[anchor]) + fit.a + fit.b * k_min;
  return tb;
}

}  // namespace msmcal::hall

#include "sessions/report/verdict.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace msmcal::report {
namespace {

std::string Fmt(const char* format, double v) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

Level Worse(Level a, Level b) { return static_cast<int>(a) > static_cast<int>(b) ? a : b; }

// Inverse of the standard normal CDF (Acklam's rational approximation, relative error < 1.2e-9).
double NormalQuantile(double p) {
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  const double lo = 0.02425, hi = 1 - lo;
  if (p < lo) {
    const double q = std::sqrt(-2 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  if (p > hi) return -NormalQuantile(1 - p);
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}

}  // namespace

const char* ToString(Level level) {
  switch (level) {
    case Level::kPass:
      return "pass";
    case Level::kWarn:
      return "warn";
    case Level::kFail:
      return "fail";
  }
  return "?";
}

Level Overall(const std::vector<VerdictLine>& lines) {
  Level l = Level::kPass;
  for (const auto& v : lines) l = Worse(l, v.level);
  return l;
}

double ChiSquareQuantile(double p, double dof) {
  if (!(p > 0 && p < 1) || !(dof > 0))
    throw std::invalid_argument("ChiSquareQuantile: need 0 < p < 1 and dof > 0, got p = " +
                                std::to_string(p) + ", dof = " + std::to_string(dof));
  if (dof == 2) return -2 * std::log1p(-p);
  const double h = 2.0 / (9.0 * dof);
  const double c = 1 - h + NormalQuantile(p) * std::sqrt(h);
  return dof * c * c * c;
}

double ChiSquare2Cdf(double x) { return x <= 0 ? 0 : -std::expm1(-x / 2); }

VerdictLine JudgeNees(const std::vector<double>& normalised_errors) {
  VerdictLine v;
  v.name = "sigma honest (NEES of the held-out beam's dots)";
  const double n = static_cast<double>(normalised_errors.size());
  double sum = 0;
  for (double e : normalised_errors) sum += 2 * e * e;
  const double nees = n > 0 ? sum / n : NAN;
  const double lo = n > 0 ? ChiSquareQuantile((1 - kNeesPassProbability) / 2, 2 * n) / n : NAN;
  const double hi = n > 0 ? ChiSquareQuantile((1 + kNeesPassProbability) / 2, 2 * n) / n : NAN;
  v.figure = "mean NEES " + Fmt("%.2f", nees) + " over " +
             std::to_string(normalised_errors.size()) + " dots (expected 2; 95 % interval " +
             Fmt("%.2f", lo) + " .. " + Fmt("%.2f", hi) + ")";
  v.rule = "pass inside the 95 % interval of chi2(2N)/N, warn within a factor " +
           Fmt("%g", kNeesWarnFactor) + " of 2, fail beyond";
  if (n == 0 || !std::isfinite(nees)) {
    v.level = Level::kFail;
    v.figure = "no held-out dot";
  } else if (nees >= lo && nees <= hi) {
    v.level = Level::kPass;
  } else if (nees <= 2 * kNeesWarnFactor && nees >= 2 / kNeesWarnFactor) {
    v.level = Level::kWarn;
  } else {
    v.level = Level::kFail;
  }
  if (n > 0 && nees > hi) v.figure += ": sigmas over-confident";
  if (n > 0 && nees < lo) v.figure += ": sigmas pessimistic";
  return v;
}

VerdictLine JudgeEllipseCoverage(const std::vector<double>& normalised_errors) {
  VerdictLine v;
  v.name = "held-out dots inside their 1/2/3-sigma ellipses";
  const double n = static_cast<double>(normalised_errors.size());
  v.rule = "each fraction within " + Fmt("%g", kCoveragePassSe) +
           " binomial standard errors (+ half a dot) of 39.3 / 86.5 / 98.9 %: pass; within " +
           Fmt("%g", kCoverageWarnSe) + ": warn; beyond: fail";
  if (n == 0) {
    v.level = Level::kFail;
    v.figure = "no held-out dot";
    return v;
  }
  v.level = Level::kPass;
  std::string got, want;
  for (int k = 1; k <= 3; ++k) {
    // Inside the k-sigma ellipse: e^T C^-1 e = 2 ne^2 <= k^2.
    int inside = 0;
    for (double e : normalised_errors) inside += 2 * e * e <= k * k ? 1 : 0;
    const double f = inside / n, p = ChiSquare2Cdf(k * k);
    const double se = std::sqrt(p * (1 - p) / n), slack = 0.5 / n;
    const double dev = std::abs(f - p);
    if (dev > kCoverageWarnSe * se + slack)
      v.level = Worse(v.level, Level::kFail);
    else if (dev > kCoveragePassSe * se + slack)
      v.level = Worse(v.level, Level::kWarn);
    got += (k > 1 ? " / " : "") + Fmt("%.0f", 100 * f);
    want += (k > 1 ? " / " : "") + Fmt("%.0f", 100 * p);
  }
  v.figure =
      got + " % of " + std::to_string(normalised_errors.size()) + " dots (expected " + want + " %)";
  return v;
}

VerdictLine JudgePlanes(int planes_solved, int triggers_planned) {
  VerdictLine v;
  v.name = "scan planes solved against triggers planned";
  v.rule = "pass at >= " + Fmt("%.0f", 100 * kPlanesPass) +
           " %, warn at >= " + Fmt("%.0f", 100 * kPlanesWarn) + " %, fail below";
  if (triggers_planned <= 0) {
    v.level = Level::kFail;
    v.figure = std::to_string(planes_solved) + " planes, no trigger planned";
    return v;
  }
  const double f = static_cast<double>(planes_solved) / triggers_planned;
  v.figure = std::to_string(planes_solved) + " of " + std::to_string(triggers_planned) + " (" +
             Fmt("%.0f", 100 * f) + " %)";
  v.level = f >= kPlanesPass ? Level::kPass : f >= kPlanesWarn ? Level::kWarn : Level::kFail;
  return v;
}

VerdictLine JudgeDroppedFrames(int dropped, int frames, const std::string& main_reason,
                               int main_reason_count) {
  VerdictLine v;
  v.name = "frames dropped by the solver";
  v.rule = "pass at <= " + Fmt("%.0f", 100 * kDroppedPass) +
           " % of the frames, warn at <= " + Fmt("%.0f", 100 * kDroppedWarn) + " %, fail above";
  const double f = frames > 0 ? static_cast<double>(dropped) / frames : (dropped > 0 ? 1.0 : 0.0);
  v.figure = std::to_string(dropped) + " of " + std::to_string(frames) + " (" +
             Fmt("%.0f", 100 * f) + " %)";
  if (dropped > 0 && !main_reason.empty())
    v.figure += "; main reason (" + std::to_string(main_reason_count) + "): " + main_reason;
  v.level = f <= kDroppedPass ? Level::kPass : f <= kDroppedWarn ? Level::kWarn : Level::kFail;
  return v;
}

VerdictLine JudgeHallResidual(const double test_rms[3], const double noise_floor[3]) {
  VerdictLine v;
  v.name = "Hall model residual against the single-reading noise floor";
  v.rule = "test RMS / floor per output: pass at <= " + Fmt("%g", kHallFloorPass) +
           ", warn at <= " + Fmt("%g", kHallFloorWarn) + ", fail above";
  static const char* kUnits[3] = {"deg", "deg", "mm"};
  static const char* kNames[3] = {"alpha", "beta", "trans"};
  double worst = 0;
  for (int i = 0; i < 3; ++i) {
    const double r = noise_floor[i] > 0 ? test_rms[i] / noise_floor[i] : INFINITY;
    worst = std::max(worst, std::isfinite(r) ? r : INFINITY);
    v.figure += std::string(i ? "; " : "") + kNames[i] + " " + Fmt("%.3g", test_rms[i]) + " / " +
                Fmt("%.3g", noise_floor[i]) + " " + kUnits[i] + " (x" + Fmt("%.1f", r) + ")";
  }
  v.level = worst <= kHallFloorPass   ? Level::kPass
            : worst <= kHallFloorWarn ? Level::kWarn
                                      : Level::kFail;
  return v;
}

VerdictLine JudgeDeltaT(double delta_t_s, double sigma_s, double search_min_s,
                        double search_max_s) {
  VerdictLine v;
  v.name = "Hall time offset delta_t";
  v.figure = Fmt("%.3f", delta_t_s * 1e3) + " ms +- " + Fmt("%.3f", sigma_s * 1e3) +
             " ms (search " + Fmt("%g", search_min_s * 1e3) + " .. " +
             Fmt("%g", search_max_s * 1e3) + " ms)";
  v.rule = "fail at a search bound; else pass at sigma <= " + Fmt("%g", kDeltaTSigmaPassS * 1e3) +
           " ms, warn at <= " + Fmt("%g", kDeltaTSigmaWarnS * 1e3) + " ms, fail above";
  const double margin = kDeltaTBoundFraction * (search_max_s - search_min_s);
  if (!std::isfinite(delta_t_s) || !std::isfinite(sigma_s) || delta_t_s <= search_min_s + margin ||
      delta_t_s >= search_max_s - margin) {
    v.level = Level::kFail;
    if (std::isfinite(delta_t_s)) v.figure += ": at the search bound";
    return v;
  }
  v.level = sigma_s <= kDeltaTSigmaPassS   ? Level::kPass
            : sigma_s <= kDeltaTSigmaWarnS ? Level::kWarn
                                           : Level::kFail;
  return v;
}

VerdictLine JudgeClock(double jitter_rms_us, int edges_used, int edges_missing,
                       int edges_rejected) {
  VerdictLine v;
  v.name = "Hall MCU clock edges";
  const int total = edges_used + edges_missing + edges_rejected;
  const double bad = total > 0 ? static_cast<double>(edges_missing + edges_rejected) / total : 1;
  v.figure = "jitter " + Fmt("%.2f", jitter_rms_us) + " us RMS, " + std::to_string(edges_used) +
             " edges used, " + std::to_string(edges_missing) + " missing, " +
             std::to_string(edges_rejected) + " rejected";
  v.rule = "pass at jitter <= " + Fmt("%g", kJitterPassUs) +
           " us and no edge missing or rejected; warn at <= " + Fmt("%g", kJitterWarnUs) +
           " us and <= " + Fmt("%.0f", 100 * kEdgesWarnFraction) + " % bad edges; fail otherwise";
  if (edges_used < 2 || !std::isfinite(jitter_rms_us))
    v.level = Level::kFail;
  else if (jitter_rms_us <= kJitterPassUs && edges_missing == 0 && edges_rejected == 0)
    v.level = Level::kPass;
  else if (jitter_rms_us <= kJitterWarnUs && bad <= kEdgesWarnFraction)
    v.level = Level::kWarn;
  else
    v.level = Level::kFail;
  return v;
}

VerdictLine JudgeReadingsLost(long long lost, long long dropped, long long expected) {
  VerdictLine v;
  v.name = "Hall readings lost or dropped";
  const long long bad = lost + std::max(0LL, dropped);
  const double f = expected > 0 ? static_cast<double>(bad) / expected : (bad > 0 ? 1.0 : 0.0);
  v.figure = std::to_string(lost) + " lost on the link, " +
             (dropped < 0 ? std::string("dropped not recorded (no journal)")
                          : std::to_string(dropped) + " dropped by the recorder") +
             ", of " + std::to_string(expected) + " expected (" + Fmt("%.3g", 100 * f) + " %)";
  v.rule = "pass at <= " + Fmt("%g", 100 * kReadingsLostPass) +
           " %, warn at <= " + Fmt("%g", 100 * kReadingsLostWarn) + " %, fail above";
  v.level = f <= kReadingsLostPass   ? Level::kPass
            : f <= kReadingsLostWarn ? Level::kWarn
                                     : Level::kFail;
  return v;
}

}  // namespace msmcal::report

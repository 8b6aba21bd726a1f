#include "processing/hall/drive_phase.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "processing/hall/delta_t.h"

namespace msmcal::hall {

std::string DrivePhaseOptions::Validate() const {
  std::ostringstream s;
  if (!(min_phase_snr > 0 && std::isfinite(min_phase_snr)))
    s << "min_phase_snr must be > 0, got " << min_phase_snr;
  else if (!(min_coherence >= 0 && min_coherence <= 1))
    s << "min_coherence must be in [0, 1], got " << min_coherence;
  else if (!(min_separation >= 0 && std::isfinite(min_separation)))
    s << "min_separation must be >= 0, got " << min_separation;
  else if (!(min_valley_separation >= 0 && min_valley_separation <= min_separation))
    s << "min_valley_separation must be in [0, min_separation], got " << min_valley_separation;
  else if (!(max_disagreement_sigmas > 0 && std::isfinite(max_disagreement_sigmas)))
    s << "max_disagreement_sigmas must be > 0, got " << max_disagreement_sigmas;
  else if (samples_per_period < 64 || samples_per_period > (1 << 22))
    s << "samples_per_period must be in [64, 4194304], got " << samples_per_period;
  return s.str();
}

namespace {

using Complex = std::complex<double>;

// The pose output's complex amplitude at each drive frequency, x(t) = Re(Z e^{i w t}), from a
// least-squares fit of [1, cos, sin (fast), cos, sin (slow)], and the phase sigma of each.
struct PoseFit {
  Complex z[2];  // fast, slow
  double phase_sigma[2] = {0, 0};
};

PoseFit FitPoseOutput(const std::vector<PoseSample>& poses, int output, const double w[2]) {
  const int n = static_cast<int>(poses.size());
  Eigen::MatrixXd x(n, 5);
  Eigen::VectorXd y(n);
  double given = 0;
  for (int j = 0; j < n; ++j) {
    const double t = poses[j].t_s;
    x.row(j) << 1, std::cos(w[0] * t), std::sin(w[0] * t), std::cos(w[1] * t), std::sin(w[1] * t);
    y[j] = poses[j].pose[output];
    given += poses[j].sigma[output] * poses[j].sigma[output] / n;
  }
  const Eigen::MatrixXd xtx = x.transpose() * x;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(xtx);
  const Eigen::VectorXd c = ldlt.solve(x.transpose() * y);
  // The residual's variance, never below the poses' own (a fit with 3 degrees of freedom can
  // land far below it by chance).
  const double s2 = std::max((y - x * c).squaredNorm() / (n - 5), given);
  const Eigen::MatrixXd cov = s2 * ldlt.solve(Eigen::MatrixXd::Identity(5, 5));
  PoseFit f;
  for (int d = 0; d < 2; ++d) {
    const double p = c[1 + 2 * d], q = c[2 + 2 * d];
    f.z[d] = Complex(p, -q);
    const double a2 = p * p + q * q;
    if (!(a2 > 0)) {
      f.phase_sigma[d] = std::numeric_limits<double>::infinity();
      continue;
    }
    const Eigen::Vector2d g(q / a2, -p / a2);  // d phase / d (p, q), phase = atan2(-q, p)
    const Eigen::Matrix2d cpq = cov.block<2, 2>(1 + 2 * d, 1 + 2 * d);
    f.phase_sigma[d] = std::sqrt(std::max(0.0, g.dot(cpq * g)));
  }
  return f;
}

std::string Fixed1(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

// The representative of x modulo m nearest c.
double Nearest(double x, double m, double c) { return x + m * std::round((c - x) / m); }

}  // namespace

DrivePhaseEstimate EstimateDeltaTFromDrivePhases(const std::vector<PoseSample>& poses,
                                                 const FieldFunction& foreground,
                                                 double fast_frequency_hz, double slow_frequency_hz,
                                                 double pattern_period_s, double window_min_s,
                                                 double window_max_s,
                                                 const DrivePhaseOptions& options) {
  if (const std::string e = options.Validate(); !e.empty())
    throw std::invalid_argument("DrivePhaseOptions: " + e);
  if (!(window_max_s > window_min_s))
    throw std::invalid_argument("EstimateDeltaTFromDrivePhases: window max must be > min");
  DrivePhaseEstimate r;
  r.fast.frequency_hz = fast_frequency_hz;
  r.slow.frequency_hz = slow_frequency_hz;
  const double f[2] = {fast_frequency_hz, slow_frequency_hz};
  if (!(f[0] > 0 && f[1] > 0 && pattern_period_s > 0) || !std::isfinite(f[0] * f[1])) {
    r.reason = "needs both drive frequencies and the pattern period";
    return r;
  }
  for (double fk : f) {
    const double cycles = fk * pattern_period_s;
    if (std::abs(cycles - std::round(cycles)) > 1e-6 * std::max(1.0, cycles) || cycles < 0.5) {
      r.reason = "the pattern period does not hold whole cycles of both drives";
      return r;
    }
  }
  if (poses.size() <= 5) {
    r.reason =
        "needs more than 5 poses for the drives' sine fit, got " + std::to_string(poses.size());
    return r;
  }
  const double w[2] = {2 * M_PI * f[0], 2 * M_PI * f[1]};
  const PoseFit fits[2] = {FitPoseOutput(poses, 0, w), FitPoseOutput(poses, 1, w)};

  // The field's complex amplitudes per axis and drive, over one pattern period: at least 16
  // samples per fast cycle (a long pattern, 1 / gcd of the drives, holds thousands of cycles).
  const double fast_cycles = f[0] * pattern_period_s;
  if (fast_cycles > (1 << 20)) {
    r.reason = "the pattern period holds more than 2^20 fast cycles";
    return r;
  }
  const int n = std::max(options.samples_per_period, static_cast<int>(std::ceil(16 * fast_cycles)));
  Complex zb[3][2] = {};
  for (int s = 0; s < n; ++s) {
    const double t = pattern_period_s * s / n;
    const Eigen::Vector3d b = foreground(t);
    for (int d = 0; d < 2; ++d) {
      const Complex e = std::polar(2.0 / n, -w[d] * t);
      for (int k = 0; k < 3; ++k) zb[k][d] += b[k] * e;
    }
  }
  const double centre = 0.5 * (window_min_s + window_max_s);
  DrivePhaseDrive* drives[2] = {&r.fast, &r.slow};
  static const char* const kName[2] = {"fast", "slow"};
  for (int d = 0; d < 2; ++d) {
    DrivePhaseDrive& dr = *drives[d];
    // The pose output that carries this drive best (alpha for the fast, beta for the slow).
    const int o = fits[0].phase_sigma[d] <= fits[1].phase_sigma[d] ? 0 : 1;
    const Complex p = fits[o].z[d];
    dr.pose_output = o;
    dr.amplitude = std::abs(p);
    dr.phase_sigma_rad = fits[o].phase_sigma[d];
    Complex sum = 0;
    double norm = 0;
    for (int k = 0; k < 3; ++k) {
      const Complex c = zb[k][d] * std::conj(p);
      sum += c * c;
      norm += std::norm(c);
    }
    dr.coherence = norm > 0 ? std::abs(sum) / norm : 0.0;
    const double half = 0.5 / f[d];
    dr.delta_t_s = Nearest(-std::arg(sum) / (2 * w[d]), half, centre);
    dr.sigma_s = dr.phase_sigma_rad / w[d];
    if (!(dr.phase_sigma_rad * options.min_phase_snr <= 1)) {
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    "the poses do not determine the %s drive's phase (amplitude %.3g, phase sigma "
                    "%.3g rad)",
                    kName[d], dr.amplitude, dr.phase_sigma_rad);
      r.reason = buf;
      return r;
    }
    if (!(dr.coherence >= options.min_coherence)) {
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    "the Hall axes disagree on the %s drive's phase (coherence %.3f < %.3f)",
                    kName[d], dr.coherence, options.min_coherence);
      r.reason = buf;
      return r;
    }
  }
  const double quarter_fast = 0.25 / f[0];
  if (2 * quarter_fast > 0.5 / f[1] || 0.25 / f[1] < 0.5 * (window_max_s - window_min_s)) {
    r.reason = "the slow drive's half period (" + FormatMs(0.5 / f[1]) +
               ") does not exceed the fast drive's and the search window";
    return r;
  }
  // The fast valleys either side of the slow estimate: the nearer is the answer; the other's
  // excess chi-square says how clearly the slow drive chose.
  const double half_fast = 2 * quarter_fast;
  const double combined = std::hypot(r.slow.sigma_s, r.fast.sigma_s);
  r.delta_t_s = Nearest(r.fast.delta_t_s, half_fast, r.slow.delta_t_s);
  r.sigma_s = r.fast.sigma_s;
  const double d_best = r.delta_t_s - r.slow.delta_t_s;
  const double d_next = half_fast - std::abs(d_best);
  r.disagreement_sigmas = std::abs(d_best) / combined;
  r.separation = (d_next * d_next - d_best * d_best) / (combined * combined);
  if (!(r.disagreement_sigmas <= options.max_disagreement_sigmas)) {
    r.reason = "the drives' phases disagree: slow " + FormatMs(r.slow.delta_t_s) + " +- " +
               FormatMs(r.slow.sigma_s) + ", the nearest fast valley " + FormatMs(r.delta_t_s);
    return r;
  }
  if (r.delta_t_s < window_min_s || r.delta_t_s > window_max_s) {
    r.reason = "dt " + FormatMs(r.delta_t_s) + " lies outside the search window " +
               FormatMs(window_min_s) + " .. " + FormatMs(window_max_s);
    return r;
  }
  r.chooses_valley = r.separation >= options.min_valley_separation;
  if (!(r.separation >= options.min_separation)) {
    r.reason = "the slow drive's phase (dt " + FormatMs(r.slow.delta_t_s) + " +- " +
               FormatMs(r.slow.sigma_s) +
               ") does not choose among the fast drive's valleys every " + FormatMs(half_fast) +
               " (" + FormatMs(r.delta_t_s) + " or " +
               FormatMs(r.delta_t_s - std::copysign(half_fast, d_best)) + ", the other " +
               Fixed1(r.separation) + " variances less likely, at least " +
               Fixed1(options.min_separation) + " needed)";
    return r;
  }
  r.determined = true;
  return r;
}

}  // namespace msmcal::hall

#pragma once
// The verdict of a calibration report: pass / warn / fail lines, each with its figure and the rule
// that judged it. Every rule is a pure function of the figures it names; the thresholds are the
// constants below, documented with their reasons in docs/report.md and unit-tested
// (tests/sessions/report/verdict_test.cc). A figure that is not available gives no line (the
// report lists it as skipped), never a guessed one.

#include <string>
#include <vector>

namespace msmcal::report {

enum class Level { kPass, kWarn, kFail };
const char* ToString(Level level);  // "pass" | "warn" | "fail"

struct VerdictLine {
  Level level = Level::kPass;
  std::string name;    // what is judged ("sigma honest (NEES)")
  std::string figure;  // the measured figure ("NEES 2.31 over 18 dots, expected 2")
  std::string rule;    // the rule ("pass inside the 95 % interval of chi2(36)/18 ...")
};

// The worst level of `lines` (kPass when empty).
Level Overall(const std::vector<VerdictLine>& lines);

// ------------------------------------------------------------------ chi-square helpers

// Quantile of the chi-square distribution with `dof` degrees of freedom (Wilson-Hilferty, relative
// error below 1e-3 for dof >= 2 at the quantiles used here; exact for dof = 2). `p` in (0, 1).
double ChiSquareQuantile(double p, double dof);
// P(X <= x) for X ~ chi2(2): 1 - exp(-x / 2). The fraction of 2-D Gaussian errors inside their
// k-sigma ellipse is ChiSquare2Cdf(k * k) (39.3 %, 86.5 %, 98.9 % for k = 1, 2, 3).
double ChiSquare2Cdf(double x);

// ------------------------------------------------------------------------- the rules

// Held-out beam: sigma honesty. `normalised_errors` are sqrt(d^2 / 2) per dot for mutually
// independent 2-D errors, d^2 = e^T C^-1 e, so a dot's NEES is 2 ne^2 ~ chi2(2) when C is
// honest: the session report passes the jointly whitened errors (validation_dots.csv,
// ne = |w| / sqrt 2), not validation_detail.csv's marginal normalised_error (the dots of one
// beam share its error, so those are correlated and N of them are not N draws). The mean NEES
// over N dots times N is chi2(2N): pass inside its two-sided 95 % interval, warn inside a
// factor kNeesWarnFactor of 2 (sigmas off by less than sqrt of it), fail outside.
inline constexpr double kNeesPassProbability = 0.95;
inline constexpr double kNeesWarnFactor = 2.0;
VerdictLine JudgeNees(const std::vector<double>& normalised_errors);

// Held-out beam (the same independent errors): the fraction of dots inside their k-sigma
// ellipse (k = 1, 2, 3) against ChiSquare2Cdf(k^2). Pass when every fraction is within
// kCoveragePassSe binomial standard errors sqrt(p (1 - p) / N) (plus half a dot, 0.5 / N) of its
// expectation, warn within kCoverageWarnSe, fail beyond. The line's level is the worst of the
// three.
inline constexpr double kCoveragePassSe = 2.0;
inline constexpr double kCoverageWarnSe = 3.0;
VerdictLine JudgeEllipseCoverage(const std::vector<double>& normalised_errors);

// Scan planes solved against the triggers planned for the scan frames: pass at >= kPlanesPass of
// them, warn at >= kPlanesWarn, fail below (too few poses leave the Hall model under-determined).
inline constexpr double kPlanesPass = 0.9;
inline constexpr double kPlanesWarn = 0.7;
VerdictLine JudgePlanes(int planes_solved, int triggers_planned);

// Frames dropped by the solver, with the most common reason: pass at <= kDroppedPass of the
// frames, warn at <= kDroppedWarn, fail above.
inline constexpr double kDroppedPass = 0.05;
inline constexpr double kDroppedWarn = 0.20;
VerdictLine JudgeDroppedFrames(int dropped, int frames, const std::string& main_reason,
                               int main_reason_count);

// Hall model: test RMS per output (alpha deg, beta deg, trans mm) against the single-reading
// noise floor (the sensor's reading noise propagated through the model, same units). Pass when
// every ratio is <= kHallFloorPass, warn <= kHallFloorWarn, fail above: a model far above the
// floor misses structure in the field (or the poses are poor).
inline constexpr double kHallFloorPass = 3.0;
inline constexpr double kHallFloorWarn = 10.0;
VerdictLine JudgeHallResidual(const double test_rms[3], const double noise_floor[3]);

// The Hall time offset delta_t and its sigma (spread over the train/test splits): fail when the
// estimate is within kDeltaTBoundFraction of the search range of a bound (the minimum was not
// bracketed); otherwise pass at sigma <= kDeltaTSigmaPassS, warn at <= kDeltaTSigmaWarnS, fail
// above (at a 200 Hz fast axis, 1 ms is 72 degrees of phase).
inline constexpr double kDeltaTSigmaPassS = 0.2e-3;
inline constexpr double kDeltaTSigmaWarnS = 1.0e-3;
inline constexpr double kDeltaTBoundFraction = 0.02;
VerdictLine JudgeDeltaT(double delta_t_s, double sigma_s, double search_min_s, double search_max_s);

// The Hall MCU's clock edges (time base fit): pass at jitter <= kJitterPassUs with no edge
// missing or rejected, warn at jitter <= kJitterWarnUs with at most kEdgesWarnFraction of the
// edges missing or rejected, fail otherwise.
inline constexpr double kJitterPassUs = 5.0;
inline constexpr double kJitterWarnUs = 50.0;
inline constexpr double kEdgesWarnFraction = 0.05;
VerdictLine JudgeClock(double jitter_rms_us, int edges_used, int edges_missing, int edges_rejected);

// Hall readings lost on the link (gaps in the MCU time stamps) or dropped by the recorder (queue
// full), over the readings expected: pass at <= kReadingsLostPass of them, warn at
// <= kReadingsLostWarn, fail above. `dropped` < 0: not recorded (no journal), judged on `lost`.
inline constexpr double kReadingsLostPass = 1e-4;
inline constexpr double kReadingsLostWarn = 1e-2;
VerdictLine JudgeReadingsLost(long long lost, long long dropped, long long expected);

}  // namespace msmcal::report

#pragma once
// dt from the drives' phases: a second witness of the time offset, independent of any field
// model (issue 15: with 8 poses at a 40 deg spanning angle the linear model misfits and its
// profile minimum lies on the fast drive's half-period alias).
//
// The field is an instantaneous function of the pose, B(tau) = F(pose(tau - dt)). Over a whole
// pattern period the component of B at a drive frequency f comes only from the pose's component
// at f (the other axis moves at another frequency; products of the two fall at f_fast +- k
// f_slow; odd powers of one axis keep its phase), so per Hall axis k
//   Z_k(f) = g_k P(f) exp(-i 2 pi f dt),  g_k real (either sign),
// with Z_k the field's complex amplitude (from the folded foreground profile, dense) and P the
// pose's (a least-squares sine fit of the poses at their trigger times). The sign of g_k is
// unknown, so each drive gives dt modulo half its period:
//   dt = -arg(sum_k (Z_k conj P)^2) / (4 pi f)  (mod 1 / (2 f)).
// The slow drive (a few Hz: half its period is ~100 ms, longer than the search window) gives dt
// coarsely but without alias; the fast drive (~200 Hz) precisely but modulo 2.4 ms; the fast
// valley nearest the slow estimate is the answer. Its sigma is the fast pose phase's sigma over
// 2 pi f_fast (the field's phases, from thousands of readings, are taken as exact).
//
// Determined when: both drive frequencies are known and whole numbers of cycles fit the pattern
// period; more poses than the sine fit's 5 parameters; each drive's pose phase has a sigma of at
// most 1 / min_phase_snr rad; the Hall axes agree on each phase (coherence |sum (Z conj P)^2| /
// sum |Z conj P|^2 >= min_coherence; a coil field left in the foreground, at the drive's
// electrical phase, lowers it); the slow estimate is precise enough to choose among the fast
// valleys (the other valley beside it is at least min_separation combined variances less likely:
// (d_next^2 - d_chosen^2) / sigma^2, sigma combining the slow and the fast estimate's) and agrees
// with the valley it chose (within max_disagreement_sigmas combined sigmas); the result lies in
// the search window. With all but a smaller separation (min_valley_separation) the estimate
// still chooses the valley the final fit searches (chooses_valley) without identifying dt. The
// poses' sigmas come from the sine fit's residual (never below the poses'
// own): on a real mirror the residual holds the drives' harmonics and the axes' cross-coupling,
// which the five-parameter fit leaves out and which bias the phases by about as much.

#include <limits>
#include <string>
#include <vector>

#include "processing/hall/hall_model.h"

namespace msmcal::hall {

struct DrivePhaseOptions {
  double min_phase_snr = 10;   // 1 / (pose phase sigma, rad) per drive
  double min_coherence = 0.9;  // the Hall axes' agreement on each drive's phase
  // The other fast valley next to the slow estimate must be this much less likely (its squared
  // distance from the slow estimate minus the chosen one's, in combined variances).
  double min_separation = 25;
  // Enough to choose the valley that the final fit searches (chooses_valley), not to identify dt.
  double min_valley_separation = 9;
  double max_disagreement_sigmas = 5;  // slow vs the chosen fast valley
  // Samples of the foreground per pattern period for its Fourier coefficients (at least 16 per
  // fast cycle are taken whatever this says).
  int samples_per_period = 4096;
  std::string Validate() const;
};

struct DrivePhaseDrive {
  double frequency_hz = 0;
  int pose_output = -1;  // the pose output whose phase was used: 0 alpha, 1 beta
  double amplitude = 0;  // of that output at this frequency (deg)
  double phase_sigma_rad = std::numeric_limits<double>::quiet_NaN();
  double coherence = std::numeric_limits<double>::quiet_NaN();
  // dt modulo half the drive's period: the representative nearest the search window's centre.
  double delta_t_s = std::numeric_limits<double>::quiet_NaN();
  double sigma_s = std::numeric_limits<double>::quiet_NaN();
};

struct DrivePhaseEstimate {
  bool determined = false;      // dt identified (every check, min_separation)
  bool chooses_valley = false;  // every check but with min_valley_separation: delta_t_s's valley
                                // is the likelier one (the final fit's bracket)
  // The fast valley nearest the slow estimate (set once both phases are measured).
  double delta_t_s = std::numeric_limits<double>::quiet_NaN();
  double sigma_s = std::numeric_limits<double>::quiet_NaN();
  DrivePhaseDrive fast, slow;
  // The chosen fast valley minus the slow estimate, in combined sigmas; the other valley beside
  // the slow estimate: its excess squared distance in combined variances.
  double disagreement_sigmas = std::numeric_limits<double>::quiet_NaN();
  double separation = std::numeric_limits<double>::quiet_NaN();
  std::string reason;  // why not determined ("" when determined)
};

// Throws std::invalid_argument for bad options; every other problem is a reason.
DrivePhaseEstimate EstimateDeltaTFromDrivePhases(const std::vector<PoseSample>& poses,
                                                 const FieldFunction& foreground,
                                                 double fast_frequency_hz, double slow_frequency_hz,
                                                 double pattern_period_s, double window_min_s,
                                                 double window_max_s,
                                                 const DrivePhaseOptions& options = {});

}  // namespace msmcal::hall

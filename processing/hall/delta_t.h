#pragma once
// Whether a recording determines the time offset dt between the Hall MCU's readings and the
// generator's (camera's) time, and its value when it does.
//
// Why: dt is seen only through the fast drive's phase. The fast axis moves 4.4 deg in a quarter
// of its period (1.2 ms at 205 Hz), the slow one 0.1 deg, so the cost J(dt) of a field model
// (hall_model.h) has a sharp valley at the true dt and, the fast axis being nearly a sine,
// another one half a fast period away (a field model matches the shifted field by flipping its
// coefficients; only the drive's harmonics and the slow axis tell them apart) and further ones
// at whole periods. A short recording (few poses, a noisy folded profile) or poses that sample
// the fast phase badly leave those valleys at nearly the same cost, and the splits of the
// Table II protocol then land in one or the other: the mean of their dt, or the global minimum
// of one fit, is a number with no meaning. The sine model's dt is never the clocks' offset: its
// features are sines at the phase of the field's fundamental (coil interference included), and
// with two axes at the fast frequency any phase is a linear combination of them, so its dt
// aligns phases, not clocks.
//
// How (IdentifyDeltaT): for one field model (linear, quadratic or cubic), the profile J(dt) over
// the whole search window on every pose (ProfileDeltaT), and the model's dt on each split of the
// protocol (first pass, the whole window). dt is identified when
//  1. the fast drive frequency is known (the window's quarter-period bracket needs it);
//  2. the profile's minimum lies inside the window and inside the bracket the final fit searched
//     (not within edge_steps grid steps of either's bound: a minimum at a bound says the true
//     dt may lie beyond it). The profile reaches half a fast period beyond the window's bounds,
//     so a deeper valley just outside the window (the true dt, when the window holds only its
//     alias) is seen;
//  3. the splits agree: at least min_split_agreement of them find dt within an eighth of a fast
//     period of the minimum (a split in another valley means the data do not choose);
//  4. the splits in that valley agree closely: their standard deviation is at most max_sigma_s
//     (a short recording's splits scatter by 0.15 ms around a minimum that is itself 0.07 ms
//     off; full-size recordings scatter by 2-8 us);
//  5. the minimum is unique: every other valley of the profile (its local minima more than an
//     eighth of a fast period away, the window's ends included) costs at least min_separation
//     residual variances more: (J_other - J_min) / (J_min / dof) >= min_separation.
// Otherwise the estimate says which test failed and why, and dt is not the session's.

#include <limits>
#include <string>
#include <vector>

#include "processing/hall/hall_model.h"

namespace msmcal::hall {

struct DeltaTIdentificationOptions {
  int edge_steps = 2;                // grid steps the minimum must keep from a bound
  double min_split_agreement = 0.9;  // fraction of the splits in the minimum's valley
  double min_separation = 25;        // residual variances between the minimum and any other
  double max_sigma_s = 25e-6;        // the splits\' spread in the minimum\'s valley
  // A field model's dt and a determined drive-phase dt (an estimate that does not depend on
  // the field's shape) further apart than this many combined sigmas: one of them is biased (a
  // field model that does not fit the recording, with few poses), and dt is not identified.
  double max_phase_disagreement_sigmas = 5;
  std::string Validate() const;
};

enum class DeltaTStatus {
  kIdentified,
  kNoFastDrive,     // the fast drive frequency is unknown
  kNoFieldModel,    // only the sine model was fitted
  kAtBound,         // the minimum lies at the search window's or the bracket's bound
  kSplitsDisagree,  // the protocol's splits find dt in different valleys
  kImprecise,       // the splits in the minimum\'s valley scatter by more than max_sigma_s
  kAmbiguous,       // another valley costs nearly as little
};
// "identified" | "no fast drive" | "no field model" | "at a bound" | "splits disagree" |
// "imprecise" | "ambiguous".
const char* ToString(DeltaTStatus status);
bool ParseDeltaTStatus(const std::string& text, DeltaTStatus* status);

// What identified dt: the judged field model's cost profile (this file), or, when that does not,
// the drives' phases (drive_phase.h; CalibrateHall).
enum class DeltaTMethod { kFieldModel, kDrivePhases };
const char* ToString(DeltaTMethod method);  // "field model" | "drive phases"
bool ParseDeltaTMethod(const std::string& text, DeltaTMethod* method);

struct DeltaTEstimate {
  DeltaTStatus status = DeltaTStatus::kNoFieldModel;
  bool identified() const { return status == DeltaTStatus::kIdentified; }
  DeltaTMethod method = DeltaTMethod::kFieldModel;
  // With kDrivePhases: the field model's own verdict (status and reason), which did not identify.
  DeltaTStatus field_status = DeltaTStatus::kIdentified;
  std::string field_reason;
  HallModelKind model = HallModelKind::kLinear;                 // the field model judged
  double delta_t_s = std::numeric_limits<double>::quiet_NaN();  // the final fit's dt
  // Standard deviation of the splits' dt in the minimum's valley (the bracketed pass).
  double sigma_s = std::numeric_limits<double>::quiet_NaN();
  double profile_min_s = std::numeric_limits<double>::quiet_NaN();  // the profile's minimum
  // The lowest other valley and its cost excess in residual variances (NaN: none).
  double runner_up_s = std::numeric_limits<double>::quiet_NaN();
  double separation = std::numeric_limits<double>::quiet_NaN();
  int splits = 0, splits_agreeing = 0;          // of the first pass, in the minimum's valley
  double search_min_s = 0, search_max_s = 0;    // the search window
  double bracket_min_s = 0, bracket_max_s = 0;  // the window the final fit searched
  std::string reason;                           // why not identified ("" when identified)
};

struct DeltaTEvidence {
  // Over the search window widened by half a fast period on each side (the next valley beyond a
  // bound is seen), every pose.
  DeltaTProfile profile;
  double search_min_s = 0, search_max_s = 0;      // the search window (HallCalibrationOptions)
  double final_delta_t_s = 0;                     // the model's final fit (every pose, the bracket)
  double bracket_min_s = 0, bracket_max_s = 0;    // the final fit's window
  std::vector<double> split_delta_t_s;            // first pass: the whole window
  std::vector<double> bracketed_split_delta_t_s;  // second pass (empty: none ran)
  double fast_frequency_hz = 0;
};

// Seconds as "0.550 ms" (the reasons' format; shared by delta_t and drive_phase).
std::string FormatMs(double s);

// Judges `evidence` (see the file comment). Throws std::invalid_argument for bad options or an
// empty profile.
DeltaTEstimate IdentifyDeltaT(const DeltaTEvidence& evidence,
                              const DeltaTIdentificationOptions& options = {});

}  // namespace msmcal::hall

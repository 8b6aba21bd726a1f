// dt identification (processing/hall/delta_t.h): the judgement on closed-form cost profiles, and
// the calibration on the synthetic rig: a dt inside the quarter-period bracket is recovered, a
// dt outside the search window or a recording that cannot tell the fast drive's valleys apart is
// not reported as the session's.
#include "processing/hall/delta_t.h"

#include <gtest/gtest.h>

#include <cmath>

#include "processing/hall/calibration.h"
#include "synthetic_hall.h"

namespace msmcal::hall {
namespace {

using testing::SyntheticHallRig;

constexpr double kFast = 200;  // Hz: valleys every 2.5 ms, a quarter period 1.25 ms
constexpr double kStep = 50e-6;
constexpr int kDof = 100;

// J(dt) = 1 + 5 (1 - cos 2x) + b (1 - cos x) + c (dt - d0)^2 with x = 2 pi f (dt - d0): the
// minimum J = 1 at d0; valleys every half fast period, the alias at d0 +- 1/(2f) higher by
// 2 b + c / (2f)^2 (the fast drive's harmonics), the whole periods by c / f^2 (the slow axis).
// The residual variance is J_min / dof, so the alias's separation is (2 b + c / (2f)^2) dof.
constexpr double kEnvelope = 12800;  // c: 0.08 at half a fast period, 8 residual variances
double AliasSeparation(double b) { return (2 * b + kEnvelope * 0.25 / (kFast * kFast)) * kDof; }
// A whole fast period away: c / f^2 dof = 32 residual variances.
double PeriodSeparation() { return kEnvelope / (kFast * kFast) * kDof; }

DeltaTEvidence Evidence(double d0, double b, double lo = -0.01, double hi = 0.01) {
  DeltaTEvidence e;
  e.fast_frequency_hz = kFast;
  e.search_min_s = lo;
  e.search_max_s = hi;
  e.profile.residual_dof = kDof;
  const double half = 0.5 / kFast;
  for (double dt = lo - half; dt <= hi + half + 1e-12; dt += kStep) {
    const double x = 2 * M_PI * kFast * (dt - d0);
    e.profile.dt_s.push_back(dt);
    e.profile.cost.push_back(1 + 5 * (1 - std::cos(2 * x)) + b * (1 - std::cos(x)) +
                             kEnvelope * (dt - d0) * (dt - d0));
  }
  e.bracket_min_s = std::max(lo, d0 - 0.25 / kFast);
  e.bracket_max_s = std::min(hi, d0 + 0.25 / kFast);
  e.final_delta_t_s = d0;
  for (int k = 0; k < 20; ++k) e.split_delta_t_s.push_back(d0 + 1e-6 * (k % 5 - 2));
  return e;
}

TEST(DeltaTIdentification, AUniqueInteriorMinimumIsIdentified) {
  const double d0 = 0.6e-3;  // on the grid: -0.0125 + 262 steps
  const DeltaTEstimate r = IdentifyDeltaT(Evidence(d0, /*b=*/1.0));
  EXPECT_EQ(r.status, DeltaTStatus::kIdentified) << r.reason;
  EXPECT_TRUE(r.reason.empty());
  EXPECT_DOUBLE_EQ(r.delta_t_s, d0);
  EXPECT_NEAR(r.profile_min_s, d0, 1e-9);
  // The half-period alias is 208 residual variances higher; the lowest other valley is a whole
  // fast period away, 32 higher.
  EXPECT_NEAR(std::abs(r.runner_up_s - d0), 1 / kFast, kStep);
  EXPECT_NEAR(r.separation, PeriodSeparation(), 0.5);
  EXPECT_GT(AliasSeparation(1.0), 200);
  EXPECT_EQ(r.splits, 20);
  EXPECT_EQ(r.splits_agreeing, 20);
  EXPECT_NEAR(r.sigma_s, std::sqrt(2e-12), 1e-9);  // the splits' offsets -2..2 us
}

TEST(DeltaTIdentification, AValleyNearlyAsDeepIsAmbiguous) {
  // (2 b + c / (2f)^2) dof = 18 < 25: the alias is within noise of the minimum.
  const DeltaTEstimate r = IdentifyDeltaT(Evidence(0.6e-3, /*b=*/0.05));
  EXPECT_EQ(r.status, DeltaTStatus::kAmbiguous);
  EXPECT_NEAR(r.separation, AliasSeparation(0.05), 0.5);
  EXPECT_NE(r.reason.find("costs only 18."), std::string::npos) << r.reason;
  // Splits that scatter by more than max_sigma_s: imprecise.
  DeltaTEvidence scatter = Evidence(0.6e-3, 1.0);
  for (int k = 0; k < 20; ++k) scatter.split_delta_t_s[k] = 0.6e-3 + (k % 2 ? 40e-6 : -40e-6);
  const DeltaTEstimate s = IdentifyDeltaT(scatter);
  EXPECT_EQ(s.status, DeltaTStatus::kImprecise);
  EXPECT_NEAR(s.sigma_s, 40e-6, 1e-12);
}

TEST(DeltaTIdentification, AMinimumAtOrBeyondTheWindowBoundIsNotReported) {
  // The true dt 0.6 ms lies below the window [1, 10] ms: the window holds only its alias at
  // 3.1 ms, an interior minimum of the window; the profile half a period beyond the bound sees
  // the deeper valley.
  DeltaTEvidence beyond = Evidence(0.6e-3, 1.0, /*lo=*/1e-3, /*hi=*/10e-3);
  beyond.final_delta_t_s = 3.1e-3;
  beyond.bracket_min_s = 3.1e-3 - 0.25 / kFast;
  beyond.bracket_max_s = 3.1e-3 + 0.25 / kFast;
  for (double& dt : beyond.split_delta_t_s) dt += 2.5e-3;
  const DeltaTEstimate r = IdentifyDeltaT(beyond);
  EXPECT_EQ(r.status, DeltaTStatus::kAtBound);
  EXPECT_NEAR(r.profile_min_s, 0.6e-3, 1e-9);
  EXPECT_NE(r.reason.find("lowest beyond the search window's bound, at 0.600 ms"),
            std::string::npos)
      << r.reason;
  // A final fit at its bracket's bound.
  DeltaTEvidence edge = Evidence(0.6e-3, 1.0);
  edge.bracket_max_s = 0.6e-3 + 0.5 * kStep;
  EXPECT_EQ(IdentifyDeltaT(edge).status, DeltaTStatus::kAtBound);
}

TEST(DeltaTIdentification, ABracketAroundTheAliasOrDisagreeingSplitsAreNotReported) {
  // The bracket was centred on the alias: the final fit's interior minimum there is not the
  // window's.
  DeltaTEvidence alias = Evidence(0.6e-3, 1.0);
  alias.final_delta_t_s = 0.6e-3 - 2.5e-3;
  alias.bracket_min_s = alias.final_delta_t_s - 0.25 / kFast;
  alias.bracket_max_s = alias.final_delta_t_s + 0.25 / kFast;
  const DeltaTEstimate a = IdentifyDeltaT(alias);
  EXPECT_EQ(a.status, DeltaTStatus::kAmbiguous);
  EXPECT_NE(a.reason.find("is not the whole window's minimum at 0.600 ms"), std::string::npos)
      << a.reason;
  // Three of 20 splits in the alias's valley: 85 % < 90 %.
  DeltaTEvidence split = Evidence(0.6e-3, 1.0);
  for (int k = 0; k < 3; ++k) split.split_delta_t_s[k] -= 2.5e-3;
  const DeltaTEstimate s = IdentifyDeltaT(split);
  EXPECT_EQ(s.status, DeltaTStatus::kSplitsDisagree);
  EXPECT_EQ(s.splits_agreeing, 17);
  EXPECT_NE(s.reason.find("3 of 20 train/test splits"), std::string::npos) << s.reason;
  // Without the fast drive frequency nothing is judged.
  DeltaTEvidence none = Evidence(0.6e-3, 1.0);
  none.fast_frequency_hz = 0;
  EXPECT_EQ(IdentifyDeltaT(none).status, DeltaTStatus::kNoFastDrive);
  // Names round-trip.
  for (DeltaTStatus st :
       {DeltaTStatus::kIdentified, DeltaTStatus::kNoFastDrive, DeltaTStatus::kNoFieldModel,
        DeltaTStatus::kAtBound, DeltaTStatus::kSplitsDisagree, DeltaTStatus::kImprecise,
        DeltaTStatus::kAmbiguous}) {
    DeltaTStatus back = DeltaTStatus::kIdentified;
    ASSERT_TRUE(ParseDeltaTStatus(ToString(st), &back));
    EXPECT_EQ(back, st);
  }
  DeltaTIdentificationOptions bad;
  bad.min_split_agreement = 2;
  EXPECT_NE(bad.Validate().find("min_split_agreement"), std::string::npos);
}

// ------------------------------------------------------------------ on the synthetic Hall rig

HallCalibrationInput MakeInput(const SyntheticHallRig& rig, const dataset::HallRecording& actual,
                               const dataset::HallRecording& background,
                               std::vector<PoseSample> poses) {
  HallCalibrationInput in;
  in.actual = &actual;
  in.background = &background;
  in.pattern_period_s = rig.period;
  in.fast_frequency_hz = rig.f_fast;
  in.slow_frequency_hz = rig.f_slow;
  in.poses = std::move(poses);
  return in;
}

// A dt anywhere in the search window: the splits bracket it to +-1/4 fast period (2.9 ms at
// 86 Hz) and the field model recovers it within 0.05 ms from noisy readings (0.5 uT) and poses
// (0.02 deg, 0.005 mm).
// A field model's dt that a determined drive-phase dt contradicts by more than
// max_phase_disagreement_sigmas combined sigmas is not reported (imprecise, both figures in the
// reason); one within it stays identified, and neither an undetermined phase estimate nor a dt
// the phases themselves gave is touched.
TEST(DeltaTIdentification, AFieldModelDtTheDrivePhasesContradictIsNotReported) {
  DeltaTEstimate field;
  field.status = DeltaTStatus::kIdentified;
  field.method = DeltaTMethod::kFieldModel;
  field.model = HallModelKind::kLinear;
  field.delta_t_s = 0.599e-3;
  field.sigma_s = 7.7e-6;
  DrivePhaseEstimate phases;
  phases.determined = true;
  phases.delta_t_s = 0.5503e-3;
  phases.sigma_s = 2.0e-6;
  const DeltaTIdentificationOptions o;
  ASSERT_EQ(o.max_phase_disagreement_sigmas, 5);
  {
    DeltaTEstimate dt = field;  // 48.7 us apart, 7.96 us combined: 6.1 sigmas
    EXPECT_TRUE(CrossCheckWithDrivePhases(phases, o, &dt));
    EXPECT_FALSE(dt.identified());
    EXPECT_EQ(dt.status, DeltaTStatus::kImprecise);
    EXPECT_NE(dt.reason.find("the linear model puts dt at 0.599 ms"), std::string::npos)
        << dt.reason;
    EXPECT_NE(dt.reason.find("the drives' phases at 0.550 ms"), std::string::npos) << dt.reason;
    EXPECT_NE(dt.reason.find("6.1 combined sigmas"), std::string::npos) << dt.reason;
  }
  {
    DeltaTEstimate dt = field;
    dt.delta_t_s = 0.5503e-3 + 4.9 * std::hypot(7.7e-6, 2.0e-6);
    EXPECT_FALSE(CrossCheckWithDrivePhases(phases, o, &dt));
    EXPECT_TRUE(dt.identified());
  }
  {
    DeltaTEstimate dt = field;
    DrivePhaseEstimate undetermined = phases;
    undetermined.determined = false;
    EXPECT_FALSE(CrossCheckWithDrivePhases(undetermined, o, &dt));
    EXPECT_TRUE(dt.identified());
    dt.method = DeltaTMethod::kDrivePhases;
    EXPECT_FALSE(CrossCheckWithDrivePhases(phases, o, &dt));
    EXPECT_TRUE(dt.identified());
  }
  DeltaTIdentificationOptions bad;
  bad.max_phase_disagreement_sigmas = 0;
  EXPECT_NE(bad.Validate().find("max_phase_disagreement_sigmas"), std::string::npos);
}

TEST(DeltaTCalibration, ADelayInsideTheBracketIsRecoveredWithNoise) {
  for (double delay : {-3.1e-3, 0.6e-3, 4.7e-3}) {
    SyntheticHallRig rig;
    rig.delay_s = delay;
    const auto actual = rig.Record(20, true, 61);
    const auto background = rig.Record(10, false, 62);
    HallCalibrationOptions o;
    o.repetitions = 5;
    o.models = {HallModelKind::kLinear, HallModelKind::kSine, HallModelKind::kQuadratic};
    const HallCalibrationResult r =
        CalibrateHall(MakeInput(rig, actual, background, rig.Poses(120, 0.02, 0.005, 63)), o);
    const DeltaTEstimate& e = r.delta_t;
    ASSERT_TRUE(e.identified()) << "delay " << delay << ": " << e.reason;
    EXPECT_NEAR(e.delta_t_s, delay, 0.05e-3);
    EXPECT_NE(e.model, HallModelKind::kSine);
    EXPECT_LE(e.bracket_max_s - e.bracket_min_s, 0.5 / rig.f_fast + 1e-12);
    EXPECT_LT(e.bracket_min_s, delay);
    EXPECT_GT(e.bracket_max_s, delay);
    EXPECT_LT(e.sigma_s, 0.05e-3);
    EXPECT_GT(e.separation, o.delta_t.min_separation);
    std::printf("delay %.4f ms: dt %.4f ms +- %.4f (%s), next valley %.3f ms at %.0f variances\n",
                delay * 1e3, e.delta_t_s * 1e3, e.sigma_s * 1e3, ToString(e.model),
                e.runner_up_s * 1e3, e.separation);
  }
}

TEST(DeltaTCalibration, ADelayOutsideTheSearchWindowIsNotReported) {
  SyntheticHallRig rig;  // dt 0.6 ms
  const auto actual = rig.Record(20, true, 71);
  const auto background = rig.Record(10, false, 72);
  const auto poses = rig.Poses(120, 0.02, 0.005, 73);
  HallCalibrationOptions o;
  o.repetitions = 4;
  o.models = {HallModelKind::kQuadratic};
  for (auto [lo, hi] : {std::pair{1.5e-3, 10e-3}, std::pair{-10e-3, 0.2e-3}}) {
    o.delta_t_min_s = lo;
    o.delta_t_max_s = hi;
    const HallCalibrationResult r = CalibrateHall(MakeInput(rig, actual, background, poses), o);
    EXPECT_FALSE(r.delta_t.identified())
        << "window " << lo << " .. " << hi << ": dt " << r.delta_t.delta_t_s;
    EXPECT_EQ(r.delta_t.status, DeltaTStatus::kAtBound) << r.delta_t.reason;
    EXPECT_NE(r.delta_t.reason.find("bound"), std::string::npos) << r.delta_t.reason;
  }
}

// The only model that cannot tell the clocks: the sine model's dt is never the session's. The
// drives' phases, when they determine dt, are (method kDrivePhases, the field verdict kept).
TEST(DeltaTCalibration, TheSineModelAloneDoesNotIdentifyDt) {
  SyntheticHallRig rig;
  const auto actual = rig.Record(10, true, 81);
  const auto background = rig.Record(5, false, 82);
  for (bool phases : {false, true}) {
    HallCalibrationOptions o;
    o.repetitions = 2;
    o.models = {HallModelKind::kSine};
    if (!phases) o.drive_phase.min_phase_snr = 1e12;  // never determined
    const HallCalibrationResult r =
        CalibrateHall(MakeInput(rig, actual, background, rig.Poses(60, 0.02, 0.005, 83)), o);
    if (!phases) {
      EXPECT_EQ(r.delta_t.status, DeltaTStatus::kNoFieldModel);
      EXPECT_NE(r.delta_t.reason.find("sine model"), std::string::npos) << r.delta_t.reason;
      continue;
    }
    ASSERT_TRUE(r.delta_t.identified()) << r.drive_phase.reason;
    EXPECT_EQ(r.delta_t.method, DeltaTMethod::kDrivePhases);
    EXPECT_EQ(r.delta_t.field_status, DeltaTStatus::kNoFieldModel);
    EXPECT_NE(r.delta_t.field_reason.find("sine model"), std::string::npos);
    EXPECT_EQ(r.delta_t.reason, "");
    EXPECT_EQ(r.delta_t.delta_t_s, r.drive_phase.delta_t_s);
    EXPECT_EQ(r.delta_t.sigma_s, r.drive_phase.sigma_s);
    EXPECT_NEAR(r.delta_t.delta_t_s, rig.delay_s, 0.02e-3);
  }
}

// A short recording whose poses sample the fast drive's phase badly: 2 s (4 pattern periods),
// 18 poses every second fast period (the fast phase drifts by a few degrees per pose, as the
// tiny simulated session's trigger table does), so the fast phase and the slow one move
// together. The linear model's minimum is 0.07 ms off and its splits scatter by 0.16 ms: dt is
// not reported (imprecise).
TEST(DeltaTCalibration, AShortRecordingDoesNotReportAWrongDt) {
  SyntheticHallRig rig;
  const auto actual = rig.Record(2, true, 91);
  const auto background = rig.Record(2, false, 92);
  std::vector<PoseSample> poses;
  for (int j = 0; j < 18; ++j) {
    PoseSample s;
    s.t_s = j * 2.03 / rig.f_fast;
    s.pose = rig.Pose(s.t_s);
    poses.push_back(s);
  }
  HallCalibrationOptions o;
  o.repetitions = 10;
  const HallCalibrationResult r = CalibrateHall(MakeInput(rig, actual, background, poses), o);
  const DeltaTEstimate& e = r.delta_t;
  std::printf("short: %s (%s), dt %.4f ms +- %.4f, truth %.4f ms: %s\n", ToString(e.status),
              ToString(e.model), e.delta_t_s * 1e3, e.sigma_s * 1e3, rig.delay_s * 1e3,
              e.reason.c_str());
  EXPECT_EQ(e.status, DeltaTStatus::kImprecise) << e.reason;
  EXPECT_GT(e.sigma_s, o.delta_t.max_sigma_s);
  EXPECT_NE(e.reason.find("scatters by"), std::string::npos) << e.reason;
  EXPECT_FALSE(e.identified());
}

// Issue 15's few-pose session on the synthetic rig: 4 s / 2 s recordings at 1.5 uT, n poses,
// linear and sine models; the drives' phases on or off (never determined).
struct FewPoses {
  FewPoses(int n, int seed, bool drive_phases) {
    rig.noise_uT = 1.5;
    actual = rig.Record(4, true, 100 + seed);
    background = rig.Record(2, false, 200 + seed);
    HallCalibrationOptions o;
    o.repetitions = 10;
    o.models = {HallModelKind::kLinear, HallModelKind::kSine};
    if (!drive_phases) o.drive_phase.min_phase_snr = 1e12;
    in = MakeInput(rig, actual, background, rig.Poses(n, 0.03, 0.01, 300 + seed));
    r = CalibrateHall(in, o);
  }
  SyntheticHallRig rig;
  dataset::HallRecording actual, background;
  HallCalibrationInput in;  // points into actual and background: not copyable
  HallCalibrationResult r;
  FewPoses(const FewPoses&) = delete;
  FewPoses& operator=(const FewPoses&) = delete;
};

// Few poses (issue 15's 8-pose scene): the sine model is chosen and no field model is steady
// enough to bracket dt. The sine model's valleys every half fast period fit alike, and over the
// whole window its dt lands on an alias (-5.2 ms for a delay of 0.6 ms at 86 Hz); its final fit
// keeps the judged field model's valley, and its dt there is within 0.05 ms of the delay, at the
// same training RMS. The session's dt stays not identified.
TEST(DeltaTCalibration, TheSineModelsDtIsKeptInTheFieldModelsValley) {
  for (auto [n, seed] : {std::pair{8, 1}, std::pair{12, 1}}) {
    SCOPED_TRACE(std::to_string(n) + " poses, seed " + std::to_string(seed));
    const FewPoses s(n, seed, /*drive_phases=*/false);  // the phases never bracket (next test)
    const SyntheticHallRig& rig = s.rig;
    const HallCalibrationInput& in = s.in;
    const HallCalibrationResult& r = s.r;
    EXPECT_FALSE(r.drive_phase.determined);
    EXPECT_EQ(r.bracket, DeltaTBracket::kNone);
    ASSERT_EQ(r.best, HallModelKind::kSine);
    EXPECT_FALSE(r.delta_t.identified());
    EXPECT_EQ(r.delta_t.model, HallModelKind::kLinear);
    ASSERT_TRUE(r.sine_in_field_valley);
    const double quarter = 0.25 / rig.f_fast;
    EXPECT_NEAR(r.final_min_s, r.delta_t.profile_min_s - quarter, 1e-12);
    EXPECT_NEAR(r.final_max_s, r.delta_t.profile_min_s + quarter, 1e-12);
    EXPECT_NEAR(r.final_fit.model.delta_t_s, rig.delay_s, 0.05e-3);
    // What the final fit over the whole window finds: an alias, at the same training RMS.
    HallFitOptions whole;
    whole.fast_frequency_hz = rig.f_fast;
    whole.slow_frequency_hz = rig.f_slow;
    whole.pattern_period_s = rig.period;
    const FieldFunction f = [&](double t) { return r.foreground.Value(t); };
    const HallFitResult free = FitHallModel(HallModelKind::kSine, in.poses, f, whole);
    EXPECT_GT(std::abs(free.model.delta_t_s - rig.delay_s), quarter) << free.model.delta_t_s;
    EXPECT_LT(r.final_fit.train_rms.norm(), 1.1 * free.train_rms.norm());
  }
}

// The same sessions with the drives' phases (drive_phase.h): no field model is steady over the
// splits, so the phases bracket the splits' second pass and the final fit; the chosen model's dt
// is the clocks' valley's, and the phases' own dt is within 0.05 ms of the delay.
TEST(DeltaTCalibration, TheDrivesPhasesBracketDtWhenNoFieldModelIsSteady) {
  int by_phases = 0;
  for (auto [n, seed] : {std::pair{8, 1}, std::pair{12, 1}, std::pair{8, 2}, std::pair{8, 3}}) {
    SCOPED_TRACE(std::to_string(n) + " poses, seed " + std::to_string(seed));
    const FewPoses s(n, seed, /*drive_phases=*/true);
    const SyntheticHallRig& rig = s.rig;
    const HallCalibrationResult& r = s.r;
    ASSERT_TRUE(r.drive_phase.determined) << r.drive_phase.reason;
    EXPECT_NEAR(r.drive_phase.delta_t_s, rig.delay_s, 0.05e-3);
    EXPECT_LT(std::abs(r.drive_phase.delta_t_s - rig.delay_s), 4 * r.drive_phase.sigma_s + 2e-6);
    // Seed 2's linear model happens to be steady over the splits: its bracket has priority.
    ASSERT_NE(r.bracket, DeltaTBracket::kNone);
    if (r.bracket == DeltaTBracket::kDrivePhases) {
      ++by_phases;
      const double quarter = 0.25 / rig.f_fast;
      EXPECT_NEAR(r.final_min_s, r.drive_phase.delta_t_s - quarter, 1e-12);
      EXPECT_NEAR(r.final_max_s, r.drive_phase.delta_t_s + quarter, 1e-12);
    }
    EXPECT_FALSE(r.sine_in_field_valley);
    EXPECT_NEAR(r.final_fit.model.delta_t_s, rig.delay_s, 0.1e-3) << ToString(r.best);
    std::printf("%d poses, seed %d: phases %.4f +- %.4f ms, %s model %.4f ms, session %s\n", n,
                seed, r.drive_phase.delta_t_s * 1e3, r.drive_phase.sigma_s * 1e3, ToString(r.best),
                r.final_fit.model.delta_t_s * 1e3, ToString(r.delta_t.status));
  }
  EXPECT_EQ(by_phases, 3);
}

}  // namespace
}  // namespace msmcal::hall

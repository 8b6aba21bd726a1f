#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "processing/hall/calibration.h"
#include "synthetic_hall.h"

namespace msmcal::hall {
namespace {

using testing::SyntheticHallRig;

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

TEST(HallModel, CubicRecoversTheDelayOnCleanData) {
  SyntheticHallRig rig;
  rig.noise_uT = 0;
  const auto actual = rig.Record(30, true, 1);
  const auto background = rig.Record(15, false, 2);
  HallCalibrationOptions o;
  o.repetitions = 2;
  o.models = {HallModelKind::kCubic};
  const HallCalibrationResult r =
      CalibrateHall(MakeInput(rig, actual, background, rig.Poses(200, 0, 0, 3)), o);
  // The time base maps MCU time to generator time; the delay is what remains.
  EXPECT_NEAR(r.actual_time_base.RateErrorPpm(), rig.rate_ppm, 0.1);
  EXPECT_NEAR(r.final_fit.model.delta_t_s, rig.delay_s, 20e-6);  // 2 % of the 1 ms sampling period
  // With the true field the cubic model's own error is 0.003 deg / 0.0001 mm on this rig; the
  // folded profiles of 1 kHz readings add interpolation error.
  EXPECT_LT(r.final_fit.train_rms[0], 0.01);
  EXPECT_LT(r.final_fit.train_rms[1], 0.01);
  EXPECT_LT(r.final_fit.train_rms[2], 0.002);
}

TEST(HallModel, TableTwoProtocolRanksModelsAndMeetsThePaper) {
  SyntheticHallRig rig;  // 0.5 uT noise per axis
  const auto actual = rig.Record(60, true, 11);
  const auto background = rig.Record(30, false, 12);
  HallCalibrationOptions o;
  o.repetitions = 6;
  // Poses measured with paper-like noise (Table I: ~0.02-0.04 deg).
  const HallCalibrationResult r =
      CalibrateHall(MakeInput(rig, actual, background, rig.Poses(195, 0.02, 0.005, 13)), o);
  ASSERT_EQ(r.table.size(), 4u);
  const ModelStats& linear = r.table[0];
  const ModelStats& quadratic = r.table[2];
  const ModelStats& cubic = r.table[3];
  EXPECT_EQ(r.best, HallModelKind::kCubic);
  // Paper's sine model: 0.083 deg, 0.069 deg, 0.10 mm; ours is at or below it.
  EXPECT_LT(cubic.test_rms_mean[0], 0.083);
  EXPECT_LT(cubic.test_rms_mean[1], 0.069);
  EXPECT_LT(cubic.test_rms_mean[2], 0.10);
  for (int k = 0; k < 3; ++k) {
    EXPECT_LT(quadratic.test_rms_mean[k], linear.test_rms_mean[k]);
    EXPECT_LT(cubic.test_rms_mean[k], quadratic.test_rms_mean[k]);
  }
  // dt: a small fraction of the 1 ms sampling period.
  EXPECT_NEAR(cubic.delta_t_mean_s, rig.delay_s, 30e-6);
  // Test error is an honest out-of-sample figure: not below the training error by much.
  EXPECT_GT(cubic.test_rms_mean[1], 0.5 * cubic.train_rms_mean[1]);
}

TEST(HallModel, ModelsWithTooManyParametersForTheSplitsAreLeftOutAndNamed) {
  SyntheticHallRig rig;
  const auto actual = rig.Record(30, true, 31);
  const auto background = rig.Record(15, false, 32);
  HallCalibrationOptions o;
  o.repetitions = 3;
  // 16 poses: a training split holds 13 (8:2), too few for the cubic model's 20 features.
  const HallCalibrationResult r =
      CalibrateHall(MakeInput(rig, actual, background, rig.Poses(16, 0.02, 0.005, 33)), o);
  ASSERT_EQ(r.skipped_models.size(), 1u);
  EXPECT_EQ(r.skipped_models[0].rfind("cubic: ", 0), 0u) << r.skipped_models[0];
  EXPECT_NE(r.skipped_models[0].find("13 poses per training split"), std::string::npos)
      << r.skipped_models[0];
  ASSERT_EQ(r.table.size(), 3u);
  for (const auto& m : r.table) EXPECT_NE(m.kind, HallModelKind::kCubic);
  EXPECT_NE(r.best, HallModelKind::kCubic);
  EXPECT_EQ(r.final_fit.model.kind, r.best);
  // Only models that cannot be fitted at all make the calibration fail, naming why: the
  // cubic model alone needs a training split of more than its 20 features (26 poses at 80 %,
  // 22 held out one at a time).
  o.models = {HallModelKind::kCubic};
  try {
    CalibrateHall(MakeInput(rig, actual, background, rig.Poses(16, 0.02, 0.005, 33)), o);
    FAIL() << "no model can be fitted";
  } catch (const std::invalid_argument& e) {
    // 21 poses with one held out leave 20, as many as its features: 22 are needed.
    EXPECT_NE(std::string(e.what()).find("needs at least 22 mirror poses"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("26 for random splits of 80 %"), std::string::npos)
        << e.what();
  }
}

// The chosen model predicts held-out poses best for how precisely they were measured. Here
// trans spans ~0.3 mm and is measured to 0.5 mm (a small slow drive, a noisy offset): no model
// has skill in it. Normalised by each output's spread (before session 13), trans's noise counted
// as much as the angles, measured to 0.005 deg, and decided the ranking: on these poses the
// linear model (0.40 / 0.94 deg, 0.48 mm) was chosen over the sine model (0.026 / 0.006 deg,
// 0.52 mm); so it was for 2 of 6 pose seeds.
TEST(HallModel, ModelChoiceWeighsEachOutputByItsMeasuredPrecision) {
  SyntheticHallRig rig;
  const auto actual = rig.Record(30, true, 41);
  const auto background = rig.Record(15, false, 42);
  HallCalibrationOptions o;
  o.repetitions = 8;
  o.models = {HallModelKind::kLinear, HallModelKind::kSine, HallModelKind::kQuadratic};
  std::vector<PoseSample> poses = rig.Poses(20, 0.005, 0.5, /*seed=*/2);
  for (auto& p : poses) p.sigma = Eigen::Vector3d(0.005, 0.005, 0.5);
  const HallCalibrationResult r = CalibrateHall(MakeInput(rig, actual, background, poses), o);
  ASSERT_EQ(r.table.size(), 3u);
  const auto angles = [](const ModelStats& m) { return m.test_rms_mean.head<2>().norm(); };
  const ModelStats* best_angles = &r.table[0];
  for (const auto& m : r.table) {
    if (angles(m) < angles(*best_angles)) best_angles = &m;
    // No skill in trans: every model's held-out error is about its noise.
    EXPECT_GT(m.test_rms_mean[2], 0.3) << ToString(m.kind);
    std::printf("%-10s test RMS %.4f deg %.4f deg %.3f mm\n", ToString(m.kind), m.test_rms_mean[0],
                m.test_rms_mean[1], m.test_rms_mean[2]);
  }
  EXPECT_EQ(r.best, best_angles->kind) << ToString(r.best);
  EXPECT_EQ(r.final_fit.model.kind, r.best);
}

// A lab session's actual recording (per-frame signals): neutral frames with both drives off,
// fast-only frames with the slow drive off, then the scan frames; the poses are the scan's.
// Folded as one recording, the stretches with a drive off were averaged into the scan's
// profile; a random subset of the readings (the Table II test split) mixes them in other
// proportions in every phase bin, so its profile jumps from bin to bin: the test RMS was
// 0.19 deg / 1.08 deg (0.013 / 0.012 with the scan alone), enough to rank a model whose dt
// means nothing (sine) above the field models. The calibration keeps only the pattern periods
// with both drives running.
SyntheticHallRig SessionRig() {
  SyntheticHallRig rig;
  rig.drives = [](double t) {
    using D = SyntheticHallRig::Drives;
    return t < 6 ? D::kOff : t < 12 ? D::kFastOnly : D::kScan;
  };
  return rig;
}

TEST(DrivenPeriods, OnlyThePeriodsWithBothDrivesRunning) {
  const SyntheticHallRig rig = SessionRig();  // T = 0.5 s: off [0, 6), fast only [6, 12), scan
  const auto actual = rig.Record(24, true, 41);
  std::vector<double> t;
  std::vector<Eigen::Vector3d> b;
  MapReadings(actual, FitTimeBase(actual.clock_edges_us, rig.period), &t, &b);
  const DrivenPeriods p = SelectDrivenPeriods(t, b, rig.period, rig.f_fast, rig.f_slow);
  EXPECT_EQ(p.periods, 48);     // whole periods of the 24 s (the first one 1 ms short)
  EXPECT_EQ(p.not_driven, 24);  // [0, 12 s): drives off, then the fast one only
  EXPECT_EQ(p.margin, 1);       // [12, 12.5 s): next to the last fast-only period
  EXPECT_EQ(p.driven, 23);
  for (size_t i = 0; i < t.size(); ++i)
    ASSERT_EQ(p.use[i], t[i] >= 12.5) << "reading " << i << " at " << t[i] << " s";
  EXPECT_EQ(p.readings_used, static_cast<size_t>(std::count(p.use.begin(), p.use.end(), true)));
  // A recording that is all scan keeps every reading, its partial last period included.
  const auto scan = SyntheticHallRig().Record(24, true, 42);
  MapReadings(scan, FitTimeBase(scan.clock_edges_us, rig.period), &t, &b);
  const DrivenPeriods all = SelectDrivenPeriods(t, b, rig.period, rig.f_fast, rig.f_slow);
  EXPECT_EQ(all.not_driven, 0);
  EXPECT_EQ(all.readings_used, t.size());
  DrivenPeriodOptions bad;
  bad.min_amplitude_ratio = 0;
  EXPECT_NE(bad.Validate().find("min_amplitude_ratio"), std::string::npos);
}

TEST(HallModel, RecoversTheDelayFromASessionWithNeutralAndFastOnlyStretches) {
  const SyntheticHallRig rig = SessionRig();
  const auto actual = rig.Record(36, true, 51);  // 12 s with a drive off, 24 s of scan
  const auto background = SyntheticHallRig().Record(15, false, 52);
  HallCalibrationOptions o;
  o.repetitions = 2;
  o.models = {HallModelKind::kCubic};
  const auto poses = SyntheticHallRig().Poses(150, 0.01, 0.002, 53);  // the scan's poses
  const HallCalibrationResult r = CalibrateHall(MakeInput(rig, actual, background, poses), o);
  EXPECT_EQ(r.actual_periods.not_driven, 24);
  EXPECT_NEAR(r.final_fit.model.delta_t_s, rig.delay_s, 30e-6);
  ASSERT_EQ(r.table.size(), 1u);
  EXPECT_NEAR(r.table[0].delta_t_mean_s, rig.delay_s, 30e-6);
  EXPECT_LT(r.table[0].test_rms_mean[0], 0.03);
  EXPECT_LT(r.table[0].test_rms_mean[1], 0.03);
  EXPECT_LT(r.final_fit.train_rms[0], 0.02);
  EXPECT_LT(r.final_fit.train_rms[1], 0.02);
}

TEST(HallPredictor, RawReadingsToPoses) {
  SyntheticHallRig rig;
  rig.noise_uT = 0.2;
  const auto actual = rig.Record(30, true, 21);
  const auto background = rig.Record(15, false, 22);
  HallCalibrationOptions o;
  o.repetitions = 1;
  o.models = {HallModelKind::kCubic};
  const HallCalibrationResult r =
      CalibrateHall(MakeInput(rig, actual, background, rig.Poses(150, 0.01, 0.002, 23)), o);
  const HallPredictor p(r.final_fit.model, r.foreground.background, r.foreground.actual.Mean());
  // Fresh raw readings of the actual field: each predicts the pose at (t - dt).
  const auto live = rig.Record(2, true, 99);
  std::vector<double> t;
  std::vector<Eigen::Vector3d> raw, pose(live.readings.size());
  MapReadings(live, r.actual_time_base, &t, &raw);
  p.PredictBatch(t.data(), raw.data(), pose.data(), t.size());
  Eigen::Vector3d ss = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < t.size(); ++i) {
    EXPECT_EQ(pose[i], p.Predict(t[i], raw[i]));
    const Eigen::Vector3d e = pose[i] - rig.Pose(t[i] - p.model().delta_t_s);
    ss += e.cwiseAbs2();
  }
  const Eigen::Vector3d rms = (ss / t.size()).cwiseSqrt();
  EXPECT_LT(rms[0], 0.06);
  EXPECT_LT(rms[1], 0.06);
  EXPECT_LT(rms[2], 0.02);
}

TEST(HallModel, OptionsAndInputErrorsAreClear) {
  HallFitOptions o;
  o.grid_step_s = 0;
  EXPECT_NE(o.Validate(HallModelKind::kLinear).find("grid_step_s"), std::string::npos);
  HallFitOptions sine;
  EXPECT_NE(sine.Validate(HallModelKind::kSine).find("sine"), std::string::npos);
  SyntheticHallRig rig;
  const auto actual = rig.Record(3, true, 1);
  HallCalibrationInput in = MakeInput(rig, actual, actual, rig.Poses(5, 0, 0, 1));
  try {
    CalibrateHall(in, {});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("needs at least 6 mirror poses (each held out once, the "
                                         "rest more than the simplest model's 4 features; 8 for "
                                         "random splits of 80 %), got 5"),
              std::string::npos)
        << e.what();
  }
}

// A session with fewer scan poses than an 8:2 split needs (8: a scene whose trigger pattern has 6
// or 7 triggers) is still calibrated: each pose is held out once, the models that the remaining
// poses can determine are compared, and dt is found as with many poses. Before session 22 it was
// refused ("needs at least 8 mirror poses").
TEST(HallModel, FewerPosesThanASplitNeedsAreEvaluatedLeaveOneOut) {
  SyntheticHallRig rig;
  const auto actual = rig.Record(30, true, 51);
  const auto background = rig.Record(15, false, 52);
  for (const size_t n : {6u, 7u}) {
    SCOPED_TRACE(n);
    HallCalibrationOptions o;
    const HallCalibrationResult r =
        CalibrateHall(MakeInput(rig, actual, background, rig.Poses(n, 0.01, 0.003, 53)), o);
    EXPECT_TRUE(r.leave_one_out);
    EXPECT_EQ(r.repetitions, static_cast<int>(n));
    EXPECT_EQ(r.min_poses_for_splits, 8);
    // Linear and sine (4 features) fit n - 1 poses; quadratic (10) and cubic (20) cannot.
    ASSERT_EQ(r.table.size(), 2u);
    EXPECT_EQ(r.skipped_models.size(), 2u);
    for (const ModelStats& m : r.table) {
      ASSERT_EQ(m.split_delta_t_s.size(), n);
      // Held-out errors: finite and not below the training error by much.
      for (int k = 0; k < 3; ++k) {
        EXPECT_TRUE(std::isfinite(m.test_rms_mean[k]));
        EXPECT_GT(m.test_rms_mean[k], 0.5 * m.train_rms_mean[k]) << ToString(m.kind) << " " << k;
      }
    }
    EXPECT_TRUE(r.delta_t.identified()) << r.delta_t.reason;
    EXPECT_NEAR(r.delta_t.delta_t_s, rig.delay_s, 50e-6);
  }
  // Many poses: random splits as before.
  HallCalibrationOptions o;
  o.repetitions = 3;
  const HallCalibrationResult r =
      CalibrateHall(MakeInput(rig, actual, background, rig.Poses(8, 0.01, 0.003, 53)), o);
  EXPECT_FALSE(r.leave_one_out);
  EXPECT_EQ(r.repetitions, 3);
}

}  // namespace
}  // namespace msmcal::hall

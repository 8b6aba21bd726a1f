// dt from the drives' phases (processing/hall/drive_phase.h) on the synthetic Hall rig: the
// fast drive's phase on the slow drive's valley recovers the delay from 8 poses, wherever it lies
// in the window (also beyond a quarter fast period, where the valley choice matters), with a
// strongly nonlinear field; a foreground that still holds a coil field, too few poses or a slow
// drive that does not move are refused with their reason.
#include "processing/hall/drive_phase.h"

#include <gtest/gtest.h>

#include <cmath>

#include "processing/hall/calibration.h"
#include "synthetic_hall.h"

namespace msmcal::hall {
namespace {

using testing::SyntheticHallRig;

// The rig's magnet field at the pose dt earlier, its mean over the pattern removed (what the
// calibration's foreground is, without the readings' noise).
FieldFunction Foreground(const SyntheticHallRig& rig, double pose_scale = 1.0,
                         Eigen::Vector3d coil = Eigen::Vector3d::Zero()) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  auto raw = [&rig, pose_scale, coil](double t) {
    Eigen::Vector3d p = rig.Pose(t - rig.delay_s);
    p.head<2>() *= pose_scale;
    // A coil at the drive's electrical phase (not the mirror's): what a background recording
    // that failed to remove it would leave.
    return Eigen::Vector3d(rig.Magnet(p) + coil * std::cos(2 * M_PI * rig.f_fast * t));
  };
  const int n = 2000;
  for (int i = 0; i < n; ++i) mean += raw(rig.period * i / n) / n;
  return [raw, mean](double t) { return Eigen::Vector3d(raw(t) - mean); };
}

std::vector<PoseSample> Poses(const SyntheticHallRig& rig, int n, double sigma_deg, uint64_t seed,
                              double pose_scale = 1.0) {
  std::vector<PoseSample> poses = rig.Poses(n, 0, 0, seed);
  std::mt19937_64 rng(seed + 1000);
  std::normal_distribution<double> g(0, sigma_deg);
  for (PoseSample& p : poses) {
    p.pose.head<2>() *= pose_scale;
    p.pose[0] += g(rng);
    p.pose[1] += g(rng);
    p.sigma = Eigen::Vector3d(sigma_deg, sigma_deg, 0.005);
  }
  return poses;
}

TEST(DrivePhase, RecoversTheDelayFromEightPosesAnywhereInTheWindow) {
  int seeds = 0;
  for (double delay : {-7.3e-3, -3.1e-3, 0.6e-3, 4.7e-3, 9.1e-3}) {
    for (uint64_t seed : {1, 2, 3}) {
      SCOPED_TRACE("delay " + std::to_string(delay * 1e3) + " ms, seed " + std::to_string(seed));
      SyntheticHallRig rig;
      rig.delay_s = delay;
      const DrivePhaseEstimate e =
          EstimateDeltaTFromDrivePhases(Poses(rig, 8, 0.03, seed), Foreground(rig), rig.f_fast,
                                        rig.f_slow, rig.period, -0.01, 0.01);
      ASSERT_TRUE(e.determined) << e.reason;
      EXPECT_EQ(e.reason, "");
      EXPECT_NEAR(e.delta_t_s, delay, 0.05e-3);
      EXPECT_LT(std::abs(e.delta_t_s - delay), 4 * e.sigma_s + 2e-6) << e.sigma_s;
      EXPECT_EQ(e.fast.pose_output, 0);  // alpha carries the fast drive
      EXPECT_EQ(e.slow.pose_output, 1);  // beta the slow one
      EXPECT_GT(e.fast.coherence, 0.99);
      EXPECT_GT(e.slow.coherence, 0.99);
      EXPECT_LT(std::abs(e.slow.delta_t_s - delay), 4 * e.slow.sigma_s);
      ++seeds;
    }
  }
  EXPECT_EQ(seeds, 15);
}

// A long pattern: 205.05 Hz and 5 Hz repeat every 20 s, 4101 fast cycles; the foreground is
// sampled at 16 per fast cycle, not at the default 4096 per period: 204.8 samples per second
// would fold a field component at 204.55 Hz (whole cycles per pattern too: an interferer, a
// sideband) onto the fast drive's 205.05 Hz and turn its phase.
TEST(DrivePhase, ALongPatternPeriodIsSampledAboveTheFastDrive) {
  SyntheticHallRig rig;
  rig.f_fast = 205.05;
  rig.f_slow = 5;
  rig.period = 20;
  rig.delay_s = 0.55e-3;
  const FieldFunction field = Foreground(rig);
  const FieldFunction with_interferer = [field](double t) {
    return Eigen::Vector3d(field(t) + Eigen::Vector3d(0, 200, 0) * std::sin(2 * M_PI * 204.55 * t));
  };
  const DrivePhaseEstimate e = EstimateDeltaTFromDrivePhases(
      Poses(rig, 12, 0.01, 5), with_interferer, rig.f_fast, rig.f_slow, rig.period, -0.01, 0.01);
  ASSERT_TRUE(e.determined) << e.reason;
  EXPECT_NEAR(e.delta_t_s, rig.delay_s, 0.02e-3);
  EXPECT_GT(e.fast.coherence, 0.99);
}

// Four times the rig's angles (alpha +-8.7 deg, beta +-34 deg): the dipole's field is far from
// linear in the pose, which moves a linear field model's minimum; the fundamentals' phases stay.
TEST(DrivePhase, AStronglyNonlinearFieldKeepsThePhases) {
  SyntheticHallRig rig;
  rig.delay_s = 0.55e-3;
  const DrivePhaseEstimate e =
      EstimateDeltaTFromDrivePhases(Poses(rig, 8, 0.03, 7, 4.0), Foreground(rig, 4.0), rig.f_fast,
                                    rig.f_slow, rig.period, -0.01, 0.01);
  ASSERT_TRUE(e.determined) << e.reason;
  EXPECT_NEAR(e.delta_t_s, rig.delay_s, 0.02e-3);
}

TEST(DrivePhase, RefusesWhatDoesNotDetermineDt) {
  SyntheticHallRig rig;
  // A coil field at the fast drive's electrical phase left in the foreground (what a background
  // recording that failed to remove it leaves). On an axis the magnet's fast motion barely
  // moves (x): the axes disagree. Dominating the axis that carries the fast motion (y): the
  // fast phase moves, and the slow drive's says so.
  {
    const DrivePhaseEstimate e = EstimateDeltaTFromDrivePhases(
        Poses(rig, 8, 0.03, 1), Foreground(rig, 1.0, Eigen::Vector3d(160, 0, 0)), rig.f_fast,
        rig.f_slow, rig.period, -0.01, 0.01);
    EXPECT_FALSE(e.determined);
    EXPECT_NE(e.reason.find("Hall axes disagree on the fast drive"), std::string::npos) << e.reason;
    EXPECT_LT(e.fast.coherence, 0.9);
  }
  {
    const DrivePhaseEstimate e = EstimateDeltaTFromDrivePhases(
        Poses(rig, 8, 0.03, 1), Foreground(rig, 1.0, Eigen::Vector3d(0, 400, 0)), rig.f_fast,
        rig.f_slow, rig.period, -0.01, 0.01);
    EXPECT_FALSE(e.determined);
    EXPECT_NE(e.reason.find("the drives' phases disagree"), std::string::npos) << e.reason;
    EXPECT_GT(e.disagreement_sigmas, 5);
  }
  // Five poses: the sine fit has five parameters.
  {
    const DrivePhaseEstimate e = EstimateDeltaTFromDrivePhases(
        Poses(rig, 5, 0.03, 1), Foreground(rig), rig.f_fast, rig.f_slow, rig.period, -0.01, 0.01);
    EXPECT_FALSE(e.determined);
    EXPECT_NE(e.reason.find("more than 5 poses"), std::string::npos) << e.reason;
  }
  // The slow axis barely moves (0.001 x its angle against 0.03 deg noise): no slow phase.
  {
    const DrivePhaseEstimate e =
        EstimateDeltaTFromDrivePhases(Poses(rig, 8, 0.03, 1, 1e-3), Foreground(rig, 1e-3),
                                      rig.f_fast, rig.f_slow, rig.period, -0.01, 0.01);
    EXPECT_FALSE(e.determined);
    EXPECT_NE(e.reason.find("phase"), std::string::npos) << e.reason;
  }
  // A window that does not hold the delay.
  {
    const DrivePhaseEstimate e = EstimateDeltaTFromDrivePhases(
        Poses(rig, 8, 0.03, 1), Foreground(rig), rig.f_fast, rig.f_slow, rig.period, 2e-3, 10e-3);
    EXPECT_FALSE(e.determined);
    EXPECT_NE(e.reason.find("outside the search window"), std::string::npos) << e.reason;
    EXPECT_NEAR(e.delta_t_s, rig.delay_s, 0.05e-3);
  }
  // A pattern period that does not hold whole drive cycles; bad options.
  EXPECT_NE(EstimateDeltaTFromDrivePhases(Poses(rig, 8, 0.03, 1), Foreground(rig), rig.f_fast,
                                          rig.f_slow, 0.3, -0.01, 0.01)
                .reason.find("whole cycles"),
            std::string::npos);
  DrivePhaseOptions valley;
  valley.min_valley_separation = valley.min_separation + 1;  // must not exceed it
  EXPECT_NE(valley.Validate().find("min_valley_separation"), std::string::npos);
  DrivePhaseOptions bad;
  bad.min_coherence = 1.5;
  EXPECT_THROW(EstimateDeltaTFromDrivePhases(Poses(rig, 8, 0.03, 1), Foreground(rig), rig.f_fast,
                                             rig.f_slow, rig.period, -0.01, 0.01, bad),
               std::invalid_argument);
}

// Which valley the splits' second pass and the final fit search: a steady field model's, unless
// the drives' phases determine another one (the field model's splits agreeing on an alias, as
// the README's twin sweep once did at -1.96 ms for 0.55 ms); the phases' when no field model is
// steady and they choose a valley; else the whole window.
TEST(DrivePhase, TheBracketIsTheSteadyFieldModelsUnlessThePhasesDetermineAnotherValley) {
  const double f = 205, quarter = 0.25 / f;
  DrivePhaseEstimate phases;
  phases.delta_t_s = 0.55e-3;
  double centre = -1;
  // Nothing steady, nothing chosen.
  EXPECT_EQ(ChooseDeltaTBracket(0, HUGE_VAL, phases, f, &centre), DeltaTBracket::kNone);
  EXPECT_EQ(centre, -1);
  // A steady field model (std 20 us < 1/16 period = 0.3 ms) and no phases.
  EXPECT_EQ(ChooseDeltaTBracket(0.52e-3, 20e-6, phases, f, &centre),
            DeltaTBracket::kSteadyFieldModel);
  EXPECT_EQ(centre, 0.52e-3);
  // Phases that choose a valley but do not determine dt: the steady model keeps priority even on
  // another valley; without a steady model they bracket.
  phases.chooses_valley = true;
  EXPECT_EQ(ChooseDeltaTBracket(-1.89e-3, 20e-6, phases, f, &centre),
            DeltaTBracket::kSteadyFieldModel);
  EXPECT_EQ(centre, -1.89e-3);
  EXPECT_EQ(ChooseDeltaTBracket(2.9e-3, 1e-3, phases, f, &centre), DeltaTBracket::kDrivePhases);
  EXPECT_EQ(centre, 0.55e-3);
  // Determined phases: in the steady model's valley (within a quarter period) the steady model's
  // centre stays; in another valley the phases overrule it.
  phases.determined = true;
  EXPECT_EQ(ChooseDeltaTBracket(0.55e-3 + 0.9 * quarter, 20e-6, phases, f, &centre),
            DeltaTBracket::kSteadyFieldModel);
  EXPECT_EQ(ChooseDeltaTBracket(0.55e-3 - 0.5 / f, 20e-6, phases, f, &centre),
            DeltaTBracket::kDrivePhases);
  EXPECT_EQ(centre, 0.55e-3);
}

}  // namespace
}  // namespace msmcal::hall

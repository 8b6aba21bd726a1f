#include "processing/hall/phase_profile.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace msmcal::hall {
namespace {

Eigen::Vector3d Signal(double t) {
  return {std::sin(2 * M_PI * 6 * t), 2 * std::cos(2 * M_PI * 2 * t) + 1, 0.5 * std::sin(2 * M_PI * 20 * t + 1)};
}

TEST(PhaseProfile, FoldsManyPeriodsIntoASmoothProfile) {
  const double period = 0.5;
  std::vector<double> t;
  std::vector<Eigen::Vector3d> v;
  // 1 kHz with a 30 ppm rate error over 40 s: phases drift across the period.
  for (int i = 0; i < 40000; ++i) {
    const double ti = 17.3 + i * 1e-3 * (1 + 30e-6);
    t.push_back(ti);
    v.push_back(Signal(ti));
  }
  const PhaseProfile p = PhaseProfile::Build(t, v, period);
  double max_err = 0;
  for (double s = 0; s < 2 * period; s += 1.3e-4) max_err = std::max(max_err, (p.At(s) - Signal(s)).cwiseAbs().maxCoeff());
  EXPECT_LT(max_err, 2e-3);
  EXPECT_NEAR(p.Mean().y(), 1.0, 1e-3);
  // C1: no jump at bin boundaries, nor across the period wrap.
  const double w = p.bin_width_s();
  EXPECT_LT((p.At(period - 1e-9) - p.At(1e-9)).norm(), 1e-6);
  EXPECT_LT((p.At(3.5 * w + 1e-9) - p.At(3.5 * w - 1e-9)).norm(), 1e-6);
}

TEST(PhaseProfile, FillsEmptyBinsAndAveragesNoise) {
  std::mt19937_64 rng(5);
  const double sigma = 0.1;
  std::normal_distribution<double> noise(0, sigma);
  std::vector<double> t;
  std::vector<Eigen::Vector3d> v;
  for (int i = 0; i < 100000; ++i) {
    const double ti = std::fmod(i * 0.6180339887498949, 1.0);  // equidistributed phases
    if (ti > 0.400 && ti < 0.403) continue;  // a hole in phase
    t.push_back(ti);
    v.push_back(Signal(ti) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  PhaseProfileOptions o;
  o.readings_per_bin = 40;
  const PhaseProfile p = PhaseProfile::Build(t, v, 1.0, o);
  // Averaging 40 readings per bin: per-axis error ~ sigma / sqrt(40) = 0.016.
  double ss = 0;
  int n = 0;
  for (double s = 0.0005; s < 1.0; s += 0.001, ++n) ss += (p.At(s) - Signal(s)).squaredNorm() / 3;
  EXPECT_LT(std::sqrt(ss / n), 2 * sigma / std::sqrt(40.0));
  EXPECT_LT((p.At(0.4015) - Signal(0.4015)).norm(), 0.1);  // the hole is bridged linearly
}

TEST(PhaseProfile, RejectsBadInput) {
  EXPECT_THROW(PhaseProfile::Build({0, 1}, {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}, 1.0), std::invalid_argument);
  EXPECT_THROW(PhaseProfile::FromBins(1.0, {Eigen::Vector3d::Zero()}), std::invalid_argument);
}

}  // namespace
}  // namespace msmcal::hall

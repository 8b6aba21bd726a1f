#include "processing/hall/phase_profile.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace msmcal::hall {
namespace {

Eigen::Vector3d Signal(double t) {
  return {std::sin(2 * M_PI * 6 * t), 2 * std::cos(2 * M_PI * 2 * t) + 1,
          0.5 * std::sin(2 * M_PI * 20 * t + 1)};
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
  PhaseProfileOptions binned;
  binned.method = PhaseProfileOptions::Method::kBinned;
  const PhaseProfile p = PhaseProfile::Build(t, v, period, binned);
  double max_err = 0;
  for (double s = 0; s < 2 * period; s += 1.3e-4)
    max_err = std::max(max_err, (p.At(s) - Signal(s)).cwiseAbs().maxCoeff());
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
    if (ti > 0.400 && ti < 0.403) continue;                    // a hole in phase
    t.push_back(ti);
    v.push_back(Signal(ti) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  PhaseProfileOptions o;
  o.method = PhaseProfileOptions::Method::kBinned;
  o.readings_per_bin = 40;
  const PhaseProfile p = PhaseProfile::Build(t, v, 1.0, o);
  // Averaging 40 readings per bin: per-axis error ~ sigma / sqrt(40) = 0.016.
  double ss = 0;
  int n = 0;
  for (double s = 0.0005; s < 1.0; s += 0.001, ++n) ss += (p.At(s) - Signal(s)).squaredNorm() / 3;
  EXPECT_LT(std::sqrt(ss / n), 2 * sigma / std::sqrt(40.0));
  EXPECT_LT((p.At(0.4015) - Signal(0.4015)).norm(), 0.1);  // the hole is bridged linearly
}

// A 1 kHz MCU, a 0.2 s pattern (a whole number of ms) and a 35 ppm clock error: in 15 s the
// readings visit only about half of each millisecond of phase. A 205 Hz drive then needs the
// Fourier reconstruction; bins bridged linearly miss by percent of the amplitude.
TEST(PhaseProfile, FourierReconstructsPhasesTheReadingsNeverVisited) {
  const double period = 0.2;
  auto signal = [](double t) {
    return Eigen::Vector3d(
        100 * std::sin(2 * M_PI * 205 * t + 0.3) + 5 * std::sin(2 * M_PI * 410 * t),
        80 * std::sin(2 * M_PI * 5 * t), 30 * std::cos(2 * M_PI * 200 * t) + 7);
  };
  std::vector<double> t;
  std::vector<Eigen::Vector3d> v;
  for (int i = 0; i < 15000; ++i) {
    const double ti = 3.0001 + i * 1e-3 / (1 + 35e-6);
    t.push_back(ti);
    v.push_back(signal(ti));
  }
  const PhaseProfile fourier = PhaseProfile::Build(t, v, period);
  PhaseProfileOptions b;
  b.method = PhaseProfileOptions::Method::kBinned;
  const PhaseProfile binned = PhaseProfile::Build(t, v, period, b);
  double err_f = 0, err_b = 0;
  for (double s = 0; s < period; s += 1.7e-5) {
    err_f = std::max(err_f, (fourier.At(s) - signal(s)).cwiseAbs().maxCoeff());
    err_b = std::max(err_b, (binned.At(s) - signal(s)).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(err_f, 0.5);  // 0.5 % of the 100 uT drive
  EXPECT_GT(err_b, 2.0);  // why the default is Fourier
}

TEST(PhaseProfile, RejectsBadInput) {
  EXPECT_THROW(PhaseProfile::Build({0, 1}, {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}, 1.0),
               std::invalid_argument);
  EXPECT_THROW(PhaseProfile::FromBins(1.0, {Eigen::Vector3d::Zero()}), std::invalid_argument);
}

}  // namespace
}  // namespace msmcal::hall

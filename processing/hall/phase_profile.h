#pragma once
// A periodic, smooth profile of a triaxial signal over the pattern period, built by folding
// readings to their pattern phase (MSM paper Sec. V-B: "interpolate the actual and background
// recordings"). Two methods:
// - kFourier (default): the signal is periodic in T and, sampled at f_s, carries harmonics n/T
//   up to the Nyquist frequency; readings are averaged into fine phase bins and a truncated
//   Fourier series (all harmonics below f_s / 2) is fitted to the occupied bins by weighted
//   least squares with a tiny ridge. This reconstructs phases the readings never visited: with
//   a 1 kHz MCU, a pattern period of a whole number of milliseconds and a small clock rate
//   error, the readings of a short recording cover only part of each millisecond of phase, and
//   binning alone would interpolate a 200 Hz drive across 0.5 ms gaps (5 % amplitude error).
// - kBinned: readings averaged in phase bins, empty bins filled linearly (the paper's linear
//   interpolation, made periodic).
// The result is stored as values at bin centres; values between them come from a periodic
// Catmull-Rom cubic, so the profile is C1 in time (the time-offset fit needs a smooth cost).

#include <Eigen/Core>
#include <string>
#include <vector>

namespace msmcal::hall {

struct PhaseProfileOptions {
  enum class Method { kFourier, kBinned };
  Method method = Method::kFourier;
  // kFourier: highest harmonic of 1/T; 0 = every harmonic below half the sample rate (the
  // sample rate is measured from the readings' spacing).
  int max_harmonic = 0;
  // The MCU's sample period, seconds; 0 = the median spacing of the readings given. Set it when
  // profiling a random subset of a recording (its spacing is not the sample period).
  double sample_period_s = 0;
  double min_bin_width_s = 50e-6;  // finest bin (the MCU samples every 1 ms)
  double min_occupancy = 0.9;      // fraction of bins that must hold a reading
  // Average readings per bin: more averages noise down (sigma / sqrt(n)), fewer resolve faster
  // signals.
  double readings_per_bin = 3;
  std::string Validate() const;
};

// Median spacing of consecutive increasing times (a recording's sample period), seconds; 0 if
// none.
double MedianSpacing(const std::vector<double>& t_s);

class PhaseProfile {
 public:
  PhaseProfile() = default;
  // From readings at generator times t_s (any range; folded modulo period_s).
  static PhaseProfile Build(const std::vector<double>& t_s, const std::vector<Eigen::Vector3d>& values,
                            double period_s, const PhaseProfileOptions& options = {});
  // From stored bin values (bin i centred at (i + 0.5) * period / bins).
  static PhaseProfile FromBins(double period_s, std::vector<Eigen::Vector3d> bins);

  Eigen::Vector3d At(double t_s) const;
  // Mean over the period.
  const Eigen::Vector3d& Mean() const { return mean_; }
  double period_s() const { return period_s_; }
  double bin_width_s() const { return period_s_ / static_cast<double>(bins_.size()); }
  const std::vector<Eigen::Vector3d>& bins() const { return bins_; }
  bool empty() const { return bins_.empty(); }

 private:
  static PhaseProfile BuildFourier(const std::vector<double>& t_s, const std::vector<double>& phase,
                                   const std::vector<Eigen::Vector3d>& values, double period_s,
                                   const PhaseProfileOptions& options);

  double period_s_ = 0;
  std::vector<Eigen::Vector3d> bins_;
  Eigen::Vector3d mean_ = Eigen::Vector3d::Zero();
};

}  // namespace msmcal::hall

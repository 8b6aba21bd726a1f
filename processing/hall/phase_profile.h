#pragma once
// A periodic, smooth profile of a triaxial signal over the pattern period, built by folding
// readings to their pattern phase (MSM paper Sec. V-B: "interpolate the actual and background
// recordings"). Readings from many periods are averaged in phase bins (noise drops with the
// number of periods); empty bins are filled linearly; values between bin centres come from a
// periodic Catmull-Rom cubic, so the profile is C1 in time (the time-offset fit needs a smooth
// cost).

#include <Eigen/Core>
#include <string>
#include <vector>

namespace msmcal::hall {

struct PhaseProfileOptions {
  double min_bin_width_s = 50e-6;  // finest bin (the MCU samples every 1 ms)
  double min_occupancy = 0.9;      // fraction of bins that must hold a reading
  // Average readings per bin: more averages noise down (sigma / sqrt(n)), fewer resolve faster
  // signals.
  double readings_per_bin = 3;
  std::string Validate() const;
};

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
  double period_s_ = 0;
  std::vector<Eigen::Vector3d> bins_;
  Eigen::Vector3d mean_ = Eigen::Vector3d::Zero();
};

}  // namespace msmcal::hall

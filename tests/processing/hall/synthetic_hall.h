#pragma once
// A small, independent synthetic Hall rig for the calibration tests: a known pose trajectory, a
// dipole magnet on the mirror's back seen by a fixed sensor, coil interference, Earth's field,
// a sensor delay, an MCU clock with offset and rate error, 1 kHz readings.

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "common/units.h"
#include "processing/dataset/recording.h"
#include "processing/hall/hall_model.h"

namespace msmcal::hall::testing {

struct SyntheticHallRig {
  double f_fast = 86, f_slow = 4, period = 0.5;  // T = 1 / gcd(86, 4)
  double delay_s = 0.6e-3;
  double offset_us = 123456.0, rate_ppm = 35.0;
  double noise_uT = 0.5;
  Eigen::Vector3d earth{20, -5, 40};
  Eigen::Vector3d baseline_shift{3, -2, 1};  // background recording vs actual

  // The drives as a lab session plays them per step 2 frame (docs/lab-path.md, "Per-frame
  // signals"): both on (the scan), the fast one only, or both off (the neutral pose). An axis
  // that is not driven rests at 0 and its coil adds no field. Empty: always the scan.
  enum class Drives { kScan, kFastOnly, kOff };
  std::function<Drives(double t)> drives;
  Drives DrivesAt(double t) const { return drives ? drives(t) : Drives::kScan; }

  // alpha_deg, beta_deg, trans_mm at generator time t (paper-like ranges: 4.37, 17.17, 1.04).
  Eigen::Vector3d Pose(double t) const {
    const Drives d = DrivesAt(t);
    const double a = d == Drives::kOff ? 0.0
                                       : 2.185 * std::sin(2 * M_PI * f_fast * t + 0.3) +
                                             0.05 * std::sin(4 * M_PI * f_fast * t);
    const double b = d == Drives::kScan ? 8.585 * std::sin(2 * M_PI * f_slow * t + 1.0) : 0.0;
    const double tr = 0.03 * b + 0.004 * b * b - 0.15;
    return {a, b, tr};
  }
  Eigen::Vector3d Coil(double t) const {
    const Drives d = DrivesAt(t);
    const double fast = d == Drives::kOff ? 0.0 : 1.0, slow = d == Drives::kScan ? 1.0 : 0.0;
    return {fast * 5 * std::sin(2 * M_PI * f_fast * t),
            slow * 3 * std::sin(2 * M_PI * f_slow * t + 0.2),
            fast * 2 * std::sin(4 * M_PI * f_fast * t)};
  }
  // Field of the magnet (dipole) at the sensor for a pose.
  Eigen::Vector3d Magnet(const Eigen::Vector3d& pose) const {
    const double a = common::DegToRad(pose[0]), b = common::DegToRad(pose[1]);
    const Eigen::Matrix3d r = (Eigen::AngleAxisd(b, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    const Eigen::Vector3d pos = r * Eigen::Vector3d(0.4, 0, -1.5) + Eigen::Vector3d(0, 0, pose[2]);
    const Eigen::Vector3d m = r * Eigen::Vector3d(0, 0, 1);
    const Eigen::Vector3d d = Eigen::Vector3d(0, 0, -4.0) - pos;
    const double n = d.norm();
    const Eigen::Vector3d u = d / n;
    return 3.0e4 * (3 * m.dot(u) * u - m) / (n * n * n);
  }
  Eigen::Vector3d Field(double t, bool magnet, const Eigen::Vector3d& shift) const {
    Eigen::Vector3d b = Coil(t) + earth + shift;
    if (magnet) b += Magnet(Pose(t));
    return b;
  }
  double Rate() const { return 1e6 * (1 + rate_ppm * 1e-6); }

  dataset::HallRecording Record(double seconds, bool magnet, uint64_t seed) const {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0, noise_uT);
    const Eigen::Vector3d shift = magnet ? Eigen::Vector3d::Zero() : baseline_shift;
    dataset::HallRecording rec;
    const int64_t start = static_cast<int64_t>(offset_us) + 1000 + static_cast<int64_t>(seed % 7);
    for (int64_t tau = start; tau < offset_us + seconds * Rate(); tau += 1000) {
      const double t = (tau - offset_us) / Rate();
      const Eigen::Vector3d b = Field(t - delay_s, magnet, shift);
      rec.readings.push_back(
          {static_cast<double>(tau), b.x() + noise(rng), b.y() + noise(rng), b.z() + noise(rng)});
    }
    for (int k = 0; k * period < seconds; ++k)
      rec.clock_edges_us.push_back(
          static_cast<double>(std::llround(offset_us + Rate() * k * period)));
    return rec;
  }

  std::vector<PoseSample> Poses(int n, double sigma_deg, double sigma_mm, uint64_t seed) const {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, period);
    std::normal_distribution<double> g(0, 1);
    std::vector<PoseSample> out;
    for (int j = 0; j < n; ++j) {
      PoseSample s;
      s.t_s = u(rng);
      s.pose =
          Pose(s.t_s) + Eigen::Vector3d(sigma_deg * g(rng), sigma_deg * g(rng), sigma_mm * g(rng));
      out.push_back(s);
    }
    return out;
  }
};

}  // namespace msmcal::hall::testing

#include "mocks/rig/mirror_motion.h"

#include <cmath>
#include <numbers>

#include "common/units.h"

namespace msmcal::sim {

const char* ToString(DriveMode mode) {
  switch (mode) {
    case DriveMode::kOff:
      return "off";
    case DriveMode::kFastOnly:
      return "fast_only";
    case DriveMode::kScan:
      return "scan";
  }
  return "?";
}

AxisResponse ResonantResponse(const AxisOptions& axis) {
  const double r = axis.frequency_hz / axis.resonance_hz;
  const double re = 1.0 - r * r;
  const double im = r / axis.q;
  AxisResponse out;
  out.amplitude_deg = axis.dc_gain_deg_per_v * 0.5 * axis.amplitude_vpp / std::hypot(re, im);
  out.lag_rad = std::atan2(im, re);
  return out;
}

MirrorMotion::MirrorMotion(const MirrorOptions& options)
    : options_(options),
      fast_(ResonantResponse(options.fast)),
      slow_(ResonantResponse(options.slow)) {}

double MirrorMotion::AxisAngleDeg(const AxisOptions& axis, const AxisResponse& r, double t_s) {
  constexpr double kPi = std::numbers::pi;
  const double phi =
      2 * kPi * axis.frequency_hz * t_s + common::DegToRad(axis.phase_deg) - r.lag_rad;
  return r.amplitude_deg *
         (std::sin(phi) +
          axis.harmonic2_ratio * std::sin(2 * phi + common::DegToRad(axis.harmonic2_phase_deg)));
}

double MirrorMotion::AlphaDeg(double t_s, DriveMode mode) const {
  if (mode == DriveMode::kOff) return 0.0;
  return AxisAngleDeg(options_.fast, fast_, t_s);
}

double MirrorMotion::BetaDeg(double t_s, DriveMode mode) const {
  if (mode != DriveMode::kScan) return 0.0;
  return AxisAngleDeg(options_.slow, slow_, t_s);
}

geometry::MirrorPose MirrorMotion::PoseAt(double t_s, DriveMode mode) const {
  geometry::MirrorPose pose;
  if (mode == DriveMode::kOff) return pose;
  const double a = AlphaDeg(t_s, mode);
  const double b = BetaDeg(t_s, mode);
  pose.alpha_rad = a * std::numbers::pi / 180;
  pose.beta_rad = b * std::numbers::pi / 180;
  pose.trans_mm = options_.trans_offset_mm + options_.trans_k_beta_mm_per_deg * b +
                  options_.trans_k_alpha2_mm_per_deg2 * a * a +
                  options_.trans_k_beta2_mm_per_deg2 * b * b;
  return pose;
}

}  // namespace msmcal::sim

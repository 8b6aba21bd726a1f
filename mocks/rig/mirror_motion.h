#pragma once
// MSM 3-DoF motion as a function of generator time (the rig's one time base: t in seconds from
// the pattern start, the clock's rising edge).
//
// Each axis is a driven second-order resonator (AxisOptions): with drive
// u(t) = Vpp/2 sin(2 pi f t + phase), the angle is
//   A sin(phi(t)) + h A sin(2 phi(t) + psi),  phi(t) = 2 pi f t + phase - lag,
// where A and lag come from the resonant response at f. Drives off gives the neutral pose
// (0, 0, 0) exactly; fast-only turns the slow drive off.

#include "mocks/rig/sim_options.h"
#include "processing/geometry/mirror_frame.h"

namespace msmcal::sim {

enum class DriveMode { kOff, kFastOnly, kScan };
const char* ToString(DriveMode mode);

struct AxisResponse {
  double amplitude_deg = 0;  // fundamental amplitude (half peak-to-peak without harmonic)
  double lag_rad = 0;        // phase lag behind the drive, in [0, pi]
};

// Steady-state response of one axis to its drive (closed form of the second-order system).
AxisResponse ResonantResponse(const AxisOptions& axis);

class MirrorMotion {
 public:
  explicit MirrorMotion(const MirrorOptions& options);

  // Pose in {0} at generator time t (any real t; periodic with the pattern period).
  geometry::MirrorPose PoseAt(double t_s, DriveMode mode) const;
  // Angles in degrees (alpha, beta), before the translation coupling.
  double AlphaDeg(double t_s, DriveMode mode) const;
  double BetaDeg(double t_s, DriveMode mode) const;

  const AxisResponse& fast_response() const { return fast_; }
  const AxisResponse& slow_response() const { return slow_; }

 private:
  static double AxisAngleDeg(const AxisOptions& axis, const AxisResponse& r, double t_s);

  MirrorOptions options_;
  AxisResponse fast_;
  AxisResponse slow_;
};

}  // namespace msmcal::sim

#pragma once
// Attitude from one accelerometer + magnetometer sample by Gauss-Newton over the quaternion
// components (MARG paper Sec. 3, its refs. [11], [21]).
//
// Frames: the Earth frame {E} has z up, x along the horizontal component of the magnetic field
// (magnetic north), y = z x x. At rest the accelerometer measures the specific force, +1 g
// along up: a_body = body_from_earth * (0, 0, 1). The magnetic reference is
// m_E = (cos delta, 0, sin delta), delta the field's elevation (negative in the northern
// hemisphere, where the field points down).
//
// Unknown: q = earth_from_body, kept unit: each Gauss-Newton step solves for a rotation vector
// delta in q's tangent space, q <- q * Exp(delta) (d(R v)/d delta = -R [v]x), so the iterates
// minimise F on the unit sphere of quaternions. Residual (6-vector) with unit measurements:
//   eps(q) = [g_E; m_E] - [R(q) a^; R(q) m^],   cost F(q) = eps^T eps   (dimensionless).
// F is the quantity of MARG Table 1: its mean over a recording measures how inconsistent the
// accelerometer and magnetometer are (0 for perfect, noise-free data).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <vector>

namespace msmcal::marg {

struct AttitudeReference {
  Eigen::Vector3d gravity = Eigen::Vector3d::UnitZ();   // unit
  Eigen::Vector3d magnetic = Eigen::Vector3d::UnitX();  // unit

  // Reference with the given field elevation (radians, negative = pointing down).
  static AttitudeReference FromElevation(double elevation_rad);
};

struct AttitudeOptions {
  int max_iterations = 20;
  double step_tolerance = 1e-12;  // stop when |delta q| is below this
};

struct AttitudeSolution {
  Eigen::Quaterniond earth_from_body = Eigen::Quaterniond::Identity();
  double cost = 0;  // F at the solution
  int iterations = 0;
  bool valid = false;  // false if a measurement is zero/non-finite or the two are parallel
};

// Cost F(q) for unit q.
double AttitudeCost(const Eigen::Quaterniond& earth_from_body, const Eigen::Vector3d& accel,
                    const Eigen::Vector3d& mag, const AttitudeReference& reference);

// Closed-form TRIAD estimate (used as the Gauss-Newton start).
Eigen::Quaterniond TriadAttitude(const Eigen::Vector3d& accel, const Eigen::Vector3d& mag,
                                 const AttitudeReference& reference);

// Gauss-Newton from `initial` (TRIAD when empty).
AttitudeSolution SolveAttitude(const Eigen::Vector3d& accel, const Eigen::Vector3d& mag,
                               const AttitudeReference& reference,
                               const std::optional<Eigen::Quaterniond>& initial = std::nullopt,
                               const AttitudeOptions& options = {});

// Median elevation of the field relative to the measured "up" over paired samples:
// asin(a^ . m^). Returns 0 when there are no valid pairs.
double EstimateFieldElevation(const std::vector<Eigen::Vector3d>& accel,
                              const std::vector<Eigen::Vector3d>& mag);

// Z-Y-X Euler angles (radians) of earth_from_body = Rz(yaw) Ry(pitch) Rx(roll).
Eigen::Vector3d RollPitchYaw(const Eigen::Quaterniond& earth_from_body);

}  // namespace msmcal::marg

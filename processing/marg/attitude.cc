#include "processing/marg/attitude.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "processing/geometry/rigid3.h"

namespace msmcal::marg {

AttitudeReference AttitudeReference::FromElevation(double elevation_rad) {
  AttitudeReference r;
  r.magnetic = Eigen::Vector3d(std::cos(elevation_rad), 0, std::sin(elevation_rad));
  return r;
}

double AttitudeCost(const Eigen::Quaterniond& q, const Eigen::Vector3d& accel,
                    const Eigen::Vector3d& mag, const AttitudeReference& ref) {
  const Eigen::Matrix3d r = q.normalized().toRotationMatrix();
  return (ref.gravity - r * accel.normalized()).squaredNorm() +
         (ref.magnetic - r * mag.normalized()).squaredNorm();
}

Eigen::Quaterniond TriadAttitude(const Eigen::Vector3d& accel, const Eigen::Vector3d& mag,
                                 const AttitudeReference& ref) {
  auto triad = [](const Eigen::Vector3d& a, const Eigen::Vector3d& m) {
    Eigen::Matrix3d t;
    const Eigen::Vector3d t1 = a.normalized();
    const Eigen::Vector3d t2 = t1.cross(m).normalized();
    t << t1, t2, t1.cross(t2);
    return t;
  };
  const Eigen::Matrix3d r = triad(ref.gravity, ref.magnetic) * triad(accel, mag).transpose();
  return Eigen::Quaterniond(r).normalized();
}

AttitudeSolution SolveAttitude(const Eigen::Vector3d& accel, const Eigen::Vector3d& mag,
                               const AttitudeReference& ref,
                               const std::optional<Eigen::Quaterniond>& initial,
                               const AttitudeOptions& options) {
  AttitudeSolution sol;
  const double na = accel.norm(), nm = mag.norm();
  if (!(na > 0) || !(nm > 0) || !std::isfinite(na) || !std::isfinite(nm) ||
      accel.cross(mag).norm() < 1e-9 * na * nm) {
    return sol;
  }
  const Eigen::Vector3d a = accel / na, m = mag / nm;
  Eigen::Quaterniond q = initial ? initial->normalized() : TriadAttitude(a, m, ref);
  int it = 0;
  for (; it < options.max_iterations; ++it) {
    const Eigen::Matrix3d r = q.toRotationMatrix();
    Eigen::Matrix<double, 6, 1> eps;
    eps << ref.gravity - r * a, ref.magnetic - r * m;
    // eps(delta) ~ eps - J delta with J = d(R Exp(delta) v)/d delta = -R [v]x.
    Eigen::Matrix<double, 6, 3> j;
    j << -r * geometry::Skew(a), -r * geometry::Skew(m);
    const Eigen::Vector3d delta = (j.transpose() * j).ldlt().solve(j.transpose() * eps);
    q = (q * Eigen::Quaterniond(geometry::So3Exp(delta))).normalized();
    if (delta.norm() < options.step_tolerance) {
      ++it;
      break;
    }
  }
  sol.earth_from_body = q;
  if (sol.earth_from_body.w() < 0) sol.earth_from_body.coeffs() *= -1;
  sol.cost = AttitudeCost(sol.earth_from_body, a, m, ref);
  sol.iterations = it;
  sol.valid = std::isfinite(sol.cost);
  return sol;
}

double EstimateFieldElevation(const std::vector<Eigen::Vector3d>& accel,
                              const std::vector<Eigen::Vector3d>& mag) {
  std::vector<double> el;
  const size_t n = std::min(accel.size(), mag.size());
  for (size_t i = 0; i < n; ++i) {
    const double na = accel[i].norm(), nm = mag[i].norm();
    if (!(na > 0) || !(nm > 0)) continue;
    el.push_back(std::asin(std::clamp(accel[i].dot(mag[i]) / (na * nm), -1.0, 1.0)));
  }
  if (el.empty()) return 0;
  std::nth_element(el.begin(), el.begin() + static_cast<std::ptrdiff_t>(el.size() / 2), el.end());
  return el[el.size() / 2];
}

Eigen::Vector3d RollPitchYaw(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d r = q.normalized().toRotationMatrix();
  const double roll = std::atan2(r(2, 1), r(2, 2));
  const double pitch = std::asin(std::clamp(-r(2, 0), -1.0, 1.0));
  const double yaw = std::atan2(r(1, 0), r(0, 0));
  return Eigen::Vector3d(roll, pitch, yaw);
}

}  // namespace msmcal::marg

#include "processing/geometry/rigid3.h"

#include <cmath>

namespace msmcal::geometry {

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d s;
  s << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return s;
}

Eigen::Matrix3d So3Exp(const Eigen::Vector3d& w) {
  const double theta2 = w.squaredNorm();
  const Eigen::Matrix3d k = Skew(w);
  double a, b;
  if (theta2 < 1e-16) {
    a = 1.0 - theta2 / 6.0;
    b = 0.5 - theta2 / 24.0;
  } else {
    const double theta = std::sqrt(theta2);
    a = std::sin(theta) / theta;
    b = (1.0 - std::cos(theta)) / theta2;
  }
  return Eigen::Matrix3d::Identity() + a * k + b * k * k;
}

Eigen::Vector3d So3Log(const Eigen::Matrix3d& r) {
  // Through the quaternion: numerically stable over the whole range [0, pi].
  Eigen::Quaterniond q(r);
  q.normalize();
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d xyz = q.vec();
  const double s = xyz.norm();
  if (s < 1e-12) return 2.0 * xyz / q.w();  // first order: angle ~ 2 s
  const double angle = 2.0 * std::atan2(s, q.w());
  return angle * xyz / s;
}

Eigen::Matrix4d Rigid3d::ToMatrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = RotationMatrix();
  m.topRightCorner<3, 1>() = translation;
  return m;
}

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inv = rotation.conjugate();
  return Rigid3d(inv, -(inv * translation));
}

Rigid3d Rigid3d::operator*(const Rigid3d& b_from_c) const {
  return Rigid3d(rotation * b_from_c.rotation, rotation * b_from_c.translation + translation);
}

Eigen::Matrix<double, 6, 1> Rigid3d::ToMinimal() const {
  Eigen::Matrix<double, 6, 1> x;
  x.head<3>() = So3Log(RotationMatrix());
  x.tail<3>() = translation;
  return x;
}

Rigid3d Rigid3d::FromMinimal(const Eigen::Matrix<double, 6, 1>& x) {
  return Rigid3d(Eigen::Matrix3d(So3Exp(x.head<3>())), Eigen::Vector3d(x.tail<3>()));
}

double RotationDistance(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b);
}

}  // namespace msmcal::geometry

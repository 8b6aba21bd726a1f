#include "processing/geometry/camera_model.h"

#include <Eigen/Dense>
#include <cmath>
#include <sstream>

namespace msmcal::geometry {

Eigen::Matrix3d CameraModel::K() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

std::string CameraModel::Validate() const {
  std::ostringstream s;
  if (width <= 0 || height <= 0) s << "image_size must be positive, got [" << width << ", " << height << "]";
  else if (!(fx > 0) || !(fy > 0)) s << "K: focal lengths must be positive, got fx=" << fx << " fy=" << fy;
  else if (!std::isfinite(cx) || !std::isfinite(cy)) s << "K: principal point must be finite";
  else
    for (double k : distortion)
      if (!std::isfinite(k)) { s << "distortion: coefficients must be finite"; break; }
  return s.str();
}

std::optional<Eigen::Vector2d> CameraModel::Project(const Eigen::Vector3d& p) const {
  if (p.z() <= 0) return std::nullopt;
  const double intr[4] = {fx, fy, cx, cy};
  Eigen::Vector2d px;
  ProjectWith(intr, distortion.data(), p.data(), px.data());
  return px;
}

Eigen::Vector2d CameraModel::Undistort(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d target((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  Eigen::Vector2d u = target;
  // Newton iterations on distort(u) = target with a numeric 2x2 Jacobian.
  for (int it = 0; it < 30; ++it) {
    double xd, yd;
    Distort(distortion.data(), u.x(), u.y(), &xd, &yd);
    const Eigen::Vector2d r(xd - target.x(), yd - target.y());
    if (r.norm() < 1e-15) break;
    Eigen::Matrix2d j;
    const double h = 1e-7;
    for (int c = 0; c < 2; ++c) {
      Eigen::Vector2d up = u;
      up(c) += h;
      double xp, yp;
      Distort(distortion.data(), up.x(), up.y(), &xp, &yp);
      j(0, c) = (xp - xd) / h;
      j(1, c) = (yp - yd) / h;
    }
    u -= j.lu().solve(r);
  }
  return u;
}

Eigen::Vector3d CameraModel::Unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d u = Undistort(pixel);
  return Eigen::Vector3d(u.x(), u.y(), 1.0).normalized();
}

Eigen::Matrix<double, 2, 3> CameraModel::ProjectJacobian(const Eigen::Vector3d& p) const {
  const double x = p.x() / p.z(), y = p.y() / p.z();
  const double k1 = distortion[0], k2 = distortion[1], p1 = distortion[2], p2 = distortion[3],
               k3 = distortion[4];
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double dradial = k1 + 2 * k2 * r2 + 3 * k3 * r2 * r2;  // d radial / d r2
  Eigen::Matrix2d dd;  // d(xd, yd) / d(x, y)
  dd(0, 0) = radial + x * dradial * 2 * x + 2 * p1 * y + p2 * 6 * x;
  dd(0, 1) = x * dradial * 2 * y + 2 * p1 * x + p2 * 2 * y;
  dd(1, 0) = y * dradial * 2 * x + p1 * 2 * x + 2 * p2 * y;
  dd(1, 1) = radial + y * dradial * 2 * y + p1 * 6 * y + 2 * p2 * x;
  Eigen::Matrix<double, 2, 3> dn;  // d(x, y) / d p
  dn << 1 / p.z(), 0, -x / p.z(), 0, 1 / p.z(), -y / p.z();
  Eigen::Matrix2d f;
  f << fx, 0, 0, fy;
  return f * dd * dn;
}

}  // namespace msmcal::geometry

#include "processing/geometry/plane_line.h"

#include <Eigen/SVD>
#include <cmath>
#include <stdexcept>

namespace msmcal::geometry {

Plane Plane::FromPointNormal(const Eigen::Vector3d& point, const Eigen::Vector3d& normal) {
  const Eigen::Vector3d n = normal.normalized();
  return Plane{n, n.dot(point)};
}

Plane Plane::FromHomogeneous(const Eigen::Vector4d& h) {
  const double s = h.head<3>().norm();
  return Plane{h.head<3>() / s, -h.w() / s};
}

Plane TransformPlane(const Rigid3d& a_from_b, const Plane& p) {
  const Eigen::Vector3d n = a_from_b.rotation * p.n;
  return Plane{n, p.d + n.dot(a_from_b.translation)};
}

Line Line::FromPointDirection(const Eigen::Vector3d& point, const Eigen::Vector3d& direction) {
  const Eigen::Vector3d v = direction.normalized();
  return Line{v, point.cross(v)};
}

Line Line::FromTwoPoints(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  return FromPointDirection(from, to - from);
}

Line TransformLine(const Rigid3d& a_from_b, const Line& l) {
  const Eigen::Vector3d v = a_from_b.rotation * l.v;
  const Eigen::Vector3d p = a_from_b * l.ClosestPointToOrigin();
  return Line{v, p.cross(v)};
}

Line FitLine(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 2) throw std::invalid_argument("FitLine: needs at least 2 points");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::MatrixXd centred(points.size(), 3);
  for (size_t i = 0; i < points.size(); ++i) centred.row(i) = (points[i] - mean).transpose();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred, Eigen::ComputeThinV);
  Eigen::Vector3d v = svd.matrixV().col(0);
  if (v.dot(points.back() - points.front()) < 0) v = -v;
  return Line::FromPointDirection(mean, v);
}

double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

double LineLineDistance(const Line& a, const Line& b) {
  const Eigen::Vector3d c = a.v.cross(b.v);
  const double s = c.norm();
  if (s < 1e-12) return a.Distance(b.ClosestPointToOrigin());
  // Reciprocal product of Plücker lines over |v_a x v_b|.
  return std::abs(a.v.dot(b.m) + b.v.dot(a.m)) / s;
}

std::optional<Eigen::Vector3d> IntersectLinePlane(const Line& line, const Plane& plane, double* s) {
  const double denom = plane.n.dot(line.v);
  if (std::abs(denom) < 1e-12) return std::nullopt;
  const Eigen::Vector3d p0 = line.ClosestPointToOrigin();
  const double t = (plane.d - plane.n.dot(p0)) / denom;
  if (s) *s = t;
  return p0 + t * line.v;
}

std::optional<Eigen::Vector3d> IntersectRayPlane(const Eigen::Vector3d& origin,
                                                 const Eigen::Vector3d& direction,
                                                 const Plane& plane) {
  const double denom = plane.n.dot(direction);
  if (std::abs(denom) < 1e-15) return std::nullopt;
  const double t = (plane.d - plane.n.dot(origin)) / denom;
  if (t < 0) return std::nullopt;
  return origin + t * direction;
}

Eigen::Matrix4d ReflectionMatrix(const Plane& mirror) {
  Eigen::Matrix4d h = Eigen::Matrix4d::Identity();
  h.topLeftCorner<3, 3>() -= 2.0 * mirror.n * mirror.n.transpose();
  h.topRightCorner<3, 1>() = 2.0 * mirror.d * mirror.n;
  return h;
}

Eigen::Vector3d ReflectPoint(const Plane& mirror, const Eigen::Vector3d& x) {
  return x - 2.0 * mirror.SignedDistance(x) * mirror.n;
}

Eigen::Vector3d ReflectDirection(const Plane& mirror, const Eigen::Vector3d& v) {
  return v - 2.0 * mirror.n.dot(v) * mirror.n;
}

Line ReflectLine(const Plane& mirror, const Line& line) {
  const Eigen::Vector3d p = ReflectPoint(mirror, line.ClosestPointToOrigin());
  return Line::FromPointDirection(p, ReflectDirection(mirror, line.v));
}

Plane ReflectPlane(const Plane& mirror, const Plane& plane) {
  const Eigen::Vector3d n = ReflectDirection(mirror, plane.n);
  const Eigen::Vector3d p = ReflectPoint(mirror, plane.d * plane.n);
  return Plane::FromPointNormal(p, n);
}

std::optional<Line> ReflectedBeam(const Plane& mirror, const Line& incident) {
  auto hit = IntersectLinePlane(incident, mirror);
  if (!hit) return std::nullopt;
  return Line::FromPointDirection(*hit, ReflectDirection(mirror, incident.v));
}

}  // namespace msmcal::geometry

namespace msmcal::geometry {

Eigen::Vector4d LineToMinimal(const Line& line) {
  const double mn = line.m.norm();
  Eigen::Vector3d u;
  if (mn > 1e-12) {
    u = line.m / mn;
  } else {
    u = line.v.unitOrthogonal();
  }
  Eigen::Matrix3d r;
  r.col(0) = line.v;
  r.col(1) = u;
  r.col(2) = line.v.cross(u);
  Eigen::Vector4d x;
  x.head<3>() = So3Log(r);
  x(3) = mn;
  return x;
}

Line LineFromMinimal(const Eigen::Vector4d& x) {
  const Eigen::Matrix3d r = So3Exp(x.head<3>());
  return Line{r.col(0), x(3) * r.col(1)};
}

}  // namespace msmcal::geometry

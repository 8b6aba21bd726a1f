#pragma once
// Planes, lines in Plücker coordinates, reflections and intersections.
//
// Conventions (../shared/docs/interchange-format.md):
// - Plane pi = (n, d) with |n| = 1: points X with n.X = d. A mirror plane's n points to its
//   reflective side (towards the incoming beams).
// - Line L = (v, m) with |v| = 1 and moment m = p x v for any point p on the line, so that every
//   point X on L satisfies v x X + m = 0 (the constraint of the MSM paper's eq. 2; the paper's
//   text writes m = v x X-bar, which contradicts that constraint: we keep the constraint).
//   An incident beam's v points from the source towards the mirror.

#include <Eigen/Core>
#include <optional>

#include "processing/geometry/rigid3.h"

namespace msmcal::geometry {

struct Plane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  // unit normal
  double d = 0.0;                                // offset: n.X = d

  static Plane FromPointNormal(const Eigen::Vector3d& point, const Eigen::Vector3d& normal);
  // Plane (n, d) from the homogeneous 4-vector (a, b, c, -d) up to scale; the sign is kept.
  static Plane FromHomogeneous(const Eigen::Vector4d& h);
  Eigen::Vector4d Homogeneous() const { return Eigen::Vector4d(n.x(), n.y(), n.z(), -d); }
  double SignedDistance(const Eigen::Vector3d& x) const { return n.dot(x) - d; }
  Eigen::Vector3d Project(const Eigen::Vector3d& x) const { return x - SignedDistance(x) * n; }
  // The same plane with the opposite orientation.
  Plane Flipped() const { return Plane{-n, -d}; }
};

// A plane given in {b}, expressed in {a}.
Plane TransformPlane(const Rigid3d& a_from_b, const Plane& plane_in_b);

struct Line {
  Eigen::Vector3d v = Eigen::Vector3d::UnitZ();  // unit direction
  Eigen::Vector3d m = Eigen::Vector3d::Zero();   // moment, m = p x v, m.v = 0

  static Line FromPointDirection(const Eigen::Vector3d& point, const Eigen::Vector3d& direction);
  static Line FromTwoPoints(const Eigen::Vector3d& from, const Eigen::Vector3d& to);
  // The point of the line closest to the origin: v x m.
  Eigen::Vector3d ClosestPointToOrigin() const { return v.cross(m); }
  Eigen::Vector3d PointAt(double s) const { return ClosestPointToOrigin() + s * v; }
  // Signed position of the orthogonal projection of x along v.
  double Parameter(const Eigen::Vector3d& x) const { return v.dot(x - ClosestPointToOrigin()); }
  // v x X + m: zero for points on the line; its norm is the point-to-line distance.
  Eigen::Vector3d Residual(const Eigen::Vector3d& x) const { return v.cross(x) + m; }
  double Distance(const Eigen::Vector3d& x) const { return Residual(x).norm(); }
};

// A line given in {b}, expressed in {a}.
Line TransformLine(const Rigid3d& a_from_b, const Line& line_in_b);

// Least-squares line through points (PCA, MSM paper Sec. V-A1). The direction's sign is chosen
// so that it points from the first point towards the last. Needs >= 2 distinct points.
Line FitLine(const std::vector<Eigen::Vector3d>& points);

// Angle between two directions in radians, in [0, pi].
double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// Shortest distance between two lines (0 if they intersect); for parallel lines the distance
// between them.
double LineLineDistance(const Line& a, const Line& b);

// Intersection of a line with a plane. Empty when the line is parallel to the plane
// (|n.v| < 1e-12). `s` gets the line parameter of the intersection if non-null.
std::optional<Eigen::Vector3d> IntersectLinePlane(const Line& line, const Plane& plane,
                                                  double* s = nullptr);
// Ray from `origin` along `direction` (need not be unit): the intersection at a non-negative
// ray parameter, or empty.
std::optional<Eigen::Vector3d> IntersectRayPlane(const Eigen::Vector3d& origin,
                                                 const Eigen::Vector3d& direction,
                                                 const Plane& plane);

// The 4x4 reflection about a plane: H = [I - 2 n n^T, 2 d n; 0 1] (X' = X - 2 (n.X - d) n).
// The MSM paper's eq. 3 prints -2 d n in the top right block; reflecting a point of the plane
// onto itself requires +2 d n, which is what we use.
Eigen::Matrix4d ReflectionMatrix(const Plane& mirror);
Eigen::Vector3d ReflectPoint(const Plane& mirror, const Eigen::Vector3d& x);
Eigen::Vector3d ReflectDirection(const Plane& mirror, const Eigen::Vector3d& v);
// The mirror image of a line (orientation of v reflected as a direction).
Line ReflectLine(const Plane& mirror, const Line& line);
// The mirror image of a plane (orientation reflected).
Plane ReflectPlane(const Plane& mirror, const Plane& plane);
// The beam after reflection: starts where `incident` hits the mirror, travels along the
// reflected direction. Empty when the beam is parallel to the mirror.
std::optional<Line> ReflectedBeam(const Plane& mirror, const Line& incident);

}  // namespace msmcal::geometry

namespace msmcal::geometry {
// The MSM paper's 4-DoF minimal form of a line: R_L = [v, m/|m|, v x m/|m|], L~ = [Log(R_L); |m|].
// A line through the origin (m = 0) takes an arbitrary unit vector perpendicular to v.
Eigen::Vector4d LineToMinimal(const Line& line);
Line LineFromMinimal(const Eigen::Vector4d& x);
}  // namespace msmcal::geometry

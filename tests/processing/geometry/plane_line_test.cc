#include "processing/geometry/plane_line.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace msmcal::geometry {
namespace {

TEST(Plane, FromPointNormalAndDistance) {
  const Plane p = Plane::FromPointNormal(Eigen::Vector3d(0, 0, 5), Eigen::Vector3d(0, 0, 2));
  EXPECT_DOUBLE_EQ(p.d, 5.0);
  EXPECT_DOUBLE_EQ(p.SignedDistance(Eigen::Vector3d(1, 2, 8)), 3.0);
  EXPECT_TRUE(p.Project(Eigen::Vector3d(1, 2, 8)).isApprox(Eigen::Vector3d(1, 2, 5)));
  const Plane h = Plane::FromHomogeneous(p.Homogeneous() * -3.0);
  // Scale is removed, the orientation of the 4-vector is kept.
  EXPECT_TRUE(h.n.isApprox(-p.n));
  EXPECT_DOUBLE_EQ(h.d, -5.0);
}

TEST(Plane, TransformKeepsIncidence) {
  const Rigid3d a_from_b(Eigen::Matrix3d(So3Exp(Eigen::Vector3d(0.3, -0.2, 0.9))),
                         Eigen::Vector3d(4, -1, 7));
  const Plane in_b = Plane::FromPointNormal(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1, 1, 0));
  const Plane in_a = TransformPlane(a_from_b, in_b);
  for (const Eigen::Vector3d& q : {Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(2, 1, -4)}) {
    EXPECT_NEAR(in_b.SignedDistance(q), 0.0, 1e-12);
    EXPECT_NEAR(in_a.SignedDistance(a_from_b * q), 0.0, 1e-12);
  }
  // The normal keeps its side: a point in front stays in front.
  const Eigen::Vector3d front(2, 3, 3);
  EXPECT_NEAR(in_a.SignedDistance(a_from_b * front), in_b.SignedDistance(front), 1e-12);
}

TEST(Line, PluckerConstraintAndDistance) {
  const Line l = Line::FromPointDirection(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 0, 3));
  EXPECT_NEAR(l.v.norm(), 1.0, 1e-15);
  EXPECT_NEAR(l.v.dot(l.m), 0.0, 1e-15);
  // Eq. 2: v x X + m = 0 on the line.
  EXPECT_LT(l.Residual(Eigen::Vector3d(1, 0, 42)).norm(), 1e-12);
  EXPECT_NEAR(l.Distance(Eigen::Vector3d(4, 4, -3)), 5.0, 1e-12);
  EXPECT_TRUE(l.ClosestPointToOrigin().isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_NEAR(l.Parameter(Eigen::Vector3d(1, 0, 7)), 7.0, 1e-12);
}

TEST(Line, TransformKeepsIncidence) {
  const Rigid3d a_from_b(Eigen::Matrix3d(So3Exp(Eigen::Vector3d(-0.5, 0.1, 0.2))),
                         Eigen::Vector3d(10, 20, -30));
  const Line in_b = Line::FromTwoPoints(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(4, 0, -1));
  const Line in_a = TransformLine(a_from_b, in_b);
  EXPECT_LT(in_a.Distance(a_from_b * Eigen::Vector3d(1, 2, 3)), 1e-12);
  EXPECT_LT(in_a.Distance(a_from_b * Eigen::Vector3d(4, 0, -1)), 1e-12);
  EXPECT_GT(in_a.v.dot(a_from_b.rotation * (Eigen::Vector3d(4, 0, -1) - Eigen::Vector3d(1, 2, 3))), 0);
}

TEST(Line, FitLineRecoversLineAndOrientation) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 1e-3);
  const Line truth = Line::FromPointDirection(Eigen::Vector3d(5, -3, 100), Eigen::Vector3d(0.1, 0.2, -1));
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 50; ++i)
    pts.push_back(truth.PointAt(-40 + 2.0 * i) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  const Line fit = FitLine(pts);
  EXPECT_LT(AngleBetween(fit.v, truth.v), 1e-4);  // same orientation (first -> last point)
  EXPECT_LT(LineLineDistance(fit, truth), 1e-3);
  EXPECT_THROW(FitLine({Eigen::Vector3d::Zero()}), std::invalid_argument);
}

TEST(Line, LineLineDistanceClosedForm) {
  const Line x_axis = Line::FromPointDirection(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX());
  const Line skew = Line::FromPointDirection(Eigen::Vector3d(0, 0, 2.5), Eigen::Vector3d::UnitY());
  const Line parallel = Line::FromPointDirection(Eigen::Vector3d(0, 3, 4), Eigen::Vector3d::UnitX());
  EXPECT_NEAR(LineLineDistance(x_axis, skew), 2.5, 1e-12);
  EXPECT_NEAR(LineLineDistance(x_axis, parallel), 5.0, 1e-12);
}

TEST(Line, MinimalFormRoundTrip) {
  const Line l = Line::FromTwoPoints(Eigen::Vector3d(3, -2, 1), Eigen::Vector3d(-1, 5, 9));
  const Line back = LineFromMinimal(LineToMinimal(l));
  EXPECT_TRUE(back.v.isApprox(l.v, 1e-12));
  EXPECT_TRUE(back.m.isApprox(l.m, 1e-12));
  const Line through_origin = Line::FromPointDirection(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 1, 0));
  const Line back0 = LineFromMinimal(LineToMinimal(through_origin));
  EXPECT_TRUE(back0.v.isApprox(through_origin.v, 1e-12));
  EXPECT_LT(back0.m.norm(), 1e-12);
}

TEST(Intersect, LinePlaneAndRayPlane) {
  const Plane z10{Eigen::Vector3d::UnitZ(), 10};
  const Line l = Line::FromPointDirection(Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(1, 0, 1));
  double s = 0;
  const auto hit = IntersectLinePlane(l, z10, &s);
  ASSERT_TRUE(hit);
  EXPECT_TRUE(hit->isApprox(Eigen::Vector3d(11, 1, 10)));
  EXPECT_TRUE(l.PointAt(s).isApprox(*hit));
  EXPECT_FALSE(IntersectLinePlane(Line::FromPointDirection(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX()), z10));
  EXPECT_TRUE(IntersectRayPlane(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 1), z10));
  EXPECT_FALSE(IntersectRayPlane(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -1), z10));
}

TEST(Reflection, MatrixMatchesPointFormulaAndFixesThePlane) {
  const Plane mirror = Plane::FromPointNormal(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(0.3, -0.4, 1));
  const Eigen::Matrix4d h = ReflectionMatrix(mirror);
  const Eigen::Vector3d x(5, -7, 2);
  EXPECT_TRUE((h * x.homogeneous()).head<3>().isApprox(ReflectPoint(mirror, x), 1e-12));
  // A point of the mirror is fixed (the sign of the eq. 3 translation block).
  const Eigen::Vector3d on = mirror.Project(x);
  EXPECT_TRUE(ReflectPoint(mirror, on).isApprox(on, 1e-12));
  // Involution, and the reflected point is on the other side at the same distance.
  EXPECT_TRUE((h * h).isApprox(Eigen::Matrix4d::Identity(), 1e-12));
  EXPECT_NEAR(mirror.SignedDistance(ReflectPoint(mirror, x)), -mirror.SignedDistance(x), 1e-12);
  const Eigen::Matrix3d linear = h.topLeftCorner(3, 3);
  EXPECT_NEAR(linear.determinant(), -1.0, 1e-12);
}

TEST(Reflection, LawOfReflectionForABeam) {
  // Mirror z = 0 facing +z; beam coming down at 45 degrees in the XZ plane.
  const Plane mirror{Eigen::Vector3d::UnitZ(), 0};
  const Line incident = Line::FromPointDirection(Eigen::Vector3d(-10, 0, 10), Eigen::Vector3d(1, 0, -1));
  const auto out = ReflectedBeam(mirror, incident);
  ASSERT_TRUE(out);
  EXPECT_TRUE(out->v.isApprox(Eigen::Vector3d(1, 0, 1).normalized(), 1e-12));
  EXPECT_LT(out->Distance(Eigen::Vector3d::Zero()), 1e-12);
  // Eq. 3: the reflected dot X, mirrored back, lies on the incident line (virtual point).
  const Eigen::Vector3d dot = out->PointAt(out->Parameter(Eigen::Vector3d::Zero()) + 17.0);
  EXPECT_LT(incident.Distance(ReflectPoint(mirror, dot)), 1e-12);
  const Line mirrored = ReflectLine(mirror, incident);
  EXPECT_LT(mirrored.Distance(Eigen::Vector3d(-10, 0, -10)), 1e-12);
  const Plane p = ReflectPlane(mirror, Plane{Eigen::Vector3d::UnitX(), 2});
  EXPECT_TRUE(p.n.isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_NEAR(p.d, 2, 1e-12);
  const Plane q = ReflectPlane(mirror, Plane{Eigen::Vector3d::UnitZ(), 4});
  EXPECT_TRUE(q.n.isApprox(-Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(q.d, 4, 1e-12);  // the plane z = 4 becomes z = -4 with flipped normal
}

}  // namespace
}  // namespace msmcal::geometry

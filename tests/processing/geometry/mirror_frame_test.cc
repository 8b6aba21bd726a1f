#include "processing/geometry/mirror_frame.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/units.h"

namespace msmcal::geometry {
namespace {

TEST(MirrorPose, PlaneRoundTripAndDefinition) {
  const MirrorPose pose{3.1 * common::kRadPerDeg, -8.4 * common::kRadPerDeg, 0.37};
  const Plane p = PlaneFromPose(pose);
  EXPECT_NEAR(p.n.norm(), 1.0, 1e-15);
  // interchange-format.md: alpha = asin(-n_y), beta = atan2(n_x, n_z), trans = d.
  EXPECT_NEAR(std::asin(-p.n.y()), pose.alpha_rad, 1e-15);
  EXPECT_NEAR(std::atan2(p.n.x(), p.n.z()), pose.beta_rad, 1e-15);
  const MirrorPose back = PoseFromPlane(p);
  EXPECT_NEAR(back.alpha_rad, pose.alpha_rad, 1e-14);
  EXPECT_NEAR(back.beta_rad, pose.beta_rad, 1e-14);
  EXPECT_NEAR(back.trans_mm, pose.trans_mm, 1e-14);
}

TEST(MirrorPose, PositiveAlphaTiltsTheNormalTowardsMinusY) {
  // A rotation by +alpha about the fast axis X turns the normal Z towards -Y.
  const Eigen::Vector3d n = So3Exp(Eigen::Vector3d(0.1, 0, 0)) * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(PoseFromPlane(Plane{n, 0}).alpha_rad, 0.1, 1e-12);
  // A rotation by +beta about Y turns Z towards +X.
  const Eigen::Vector3d m = So3Exp(Eigen::Vector3d(0, 0.2, 0)) * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(PoseFromPlane(Plane{m, 0}).beta_rad, 0.2, 1e-12);
}

TEST(MirrorHomeFrame, AxesAndSignRules) {
  const Eigen::Vector3d n0 = Eigen::Vector3d(0.2, -0.1, 1).normalized();
  const Eigen::Vector3d centre(10, 20, 30);
  // A fast axis pointing mostly along -X_W is flipped to +X_W; its component along n0 is removed.
  const Rigid3d world_from_0 = MirrorHomeFrame(n0, Eigen::Vector3d(-1, 0.05, 0.3), centre);
  const Eigen::Matrix3d r = world_from_0.RotationMatrix();
  EXPECT_TRUE(r.col(2).isApprox(n0, 1e-12));
  EXPECT_GT(r.col(0).x(), 0);
  EXPECT_NEAR(r.col(0).dot(n0), 0, 1e-12);
  EXPECT_TRUE(r.col(1).isApprox(n0.cross(r.col(0)), 1e-12));
  EXPECT_NEAR(r.determinant(), 1, 1e-12);
  EXPECT_TRUE(world_from_0.translation.isApprox(centre));
  // |e_F . X_W| < 0.1: the sign follows Y_W.
  const Rigid3d f2 =
      MirrorHomeFrame(Eigen::Vector3d::UnitZ(), Eigen::Vector3d(0.05, -1, 0), centre);
  EXPECT_GT(f2.RotationMatrix().col(0).y(), 0);
  // The neutral plane through the centre has pose zero.
  const MirrorPose neutral = PoseFromWorldPlane(world_from_0, Plane::FromPointNormal(centre, n0));
  EXPECT_NEAR(neutral.alpha_rad, 0, 1e-12);
  EXPECT_NEAR(neutral.beta_rad, 0, 1e-12);
  EXPECT_NEAR(neutral.trans_mm, 0, 1e-12);
  const MirrorPose pose{0.02, -0.15, 0.4};
  const MirrorPose back = PoseFromWorldPlane(world_from_0, WorldPlaneFromPose(world_from_0, pose));
  EXPECT_NEAR(back.alpha_rad, pose.alpha_rad, 1e-12);
  EXPECT_NEAR(back.beta_rad, pose.beta_rad, 1e-12);
  EXPECT_NEAR(back.trans_mm, pose.trans_mm, 1e-12);
}

TEST(MirrorHomeFrame, CentreAndFastAxisFromPlanes) {
  // Planes rotating about the fast axis X through a centre: the centre is recovered by eq. 11
  // and the fast axis is the null direction of the fast-only normals.
  const Eigen::Vector3d centre(1, -2, 3);
  std::vector<Plane> fast_only, all;
  for (double a = -0.1; a <= 0.1; a += 0.05) {
    fast_only.push_back(Plane::FromPointNormal(
        centre, So3Exp(Eigen::Vector3d(a, 0, 0)) * Eigen::Vector3d::UnitZ()));
    for (double b = -0.2; b <= 0.2; b += 0.1)
      all.push_back(Plane::FromPointNormal(
          centre, So3Exp(Eigen::Vector3d(a, b, 0)) * Eigen::Vector3d::UnitZ()));
  }
  EXPECT_LT((RotationCentreFromPlanes(all) - centre).norm(), 1e-9);
  EXPECT_NEAR(std::abs(FastAxisFromPlanes(fast_only).x()), 1.0, 1e-9);
  // One fast-only plane (0.05 rad about X) with the neutral one (Z): the axis is still X; two or
  // more fast-only planes give it without the neutral.
  const Plane neutral = Plane::FromPointNormal(centre, Eigen::Vector3d::UnitZ());
  EXPECT_NEAR(std::abs(FastAxisWithNeutral(neutral, {fast_only[3]}).x()), 1.0, 1e-9);
  const Plane tilted_neutral = Plane::FromPointNormal(centre, Eigen::Vector3d(0, 0.3, 1));
  EXPECT_NEAR(std::abs(FastAxisWithNeutral(tilted_neutral, fast_only).x()), 1.0, 1e-9);
  EXPECT_THROW(FastAxisWithNeutral(neutral, {}), std::invalid_argument);
}

}  // namespace
}  // namespace msmcal::geometry

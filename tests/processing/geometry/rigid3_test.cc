#include "processing/geometry/rigid3.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace msmcal::geometry {
namespace {

TEST(So3, ExpOfAxisAngleIsRodrigues) {
  // Rotation by 90 degrees about Z maps X to Y (closed form).
  const Eigen::Matrix3d r = So3Exp(Eigen::Vector3d(0, 0, M_PI / 2));
  EXPECT_TRUE((r * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

TEST(So3, LogInvertsExpOverTheWholeRange) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (double angle : {0.0, 1e-10, 1e-5, 0.3, 1.0, 2.5, M_PI - 1e-6, M_PI - 1e-9}) {
    for (int k = 0; k < 20; ++k) {
      const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
      const Eigen::Vector3d w = angle * axis;
      const Eigen::Vector3d back = So3Log(So3Exp(w));
      EXPECT_LT((back - w).norm(), 1e-8) << "angle " << angle;
    }
  }
}

TEST(So3, SkewIsCrossProduct) {
  const Eigen::Vector3d a(1, -2, 3), b(0.5, 4, -1);
  EXPECT_TRUE((Skew(a) * b).isApprox(a.cross(b)));
}

TEST(Rigid3d, ComposeAndInverse) {
  const Rigid3d a_from_b(Eigen::Matrix3d(So3Exp(Eigen::Vector3d(0.1, 0.2, -0.3))),
                         Eigen::Vector3d(1, 2, 3));
  const Rigid3d b_from_c(Eigen::Matrix3d(So3Exp(Eigen::Vector3d(-0.4, 0.0, 0.5))),
                         Eigen::Vector3d(-5, 0, 2));
  const Eigen::Vector3d p_in_c(0.3, -0.7, 10);
  EXPECT_TRUE(((a_from_b * b_from_c) * p_in_c).isApprox(a_from_b * (b_from_c * p_in_c), 1e-12));
  EXPECT_TRUE((a_from_b.Inverse() * (a_from_b * p_in_c)).isApprox(p_in_c, 1e-12));
  EXPECT_TRUE(a_from_b.ToMatrix().inverse().isApprox(a_from_b.Inverse().ToMatrix(), 1e-12));
}

TEST(Rigid3d, MinimalRoundTrip) {
  Eigen::Matrix<double, 6, 1> x;
  x << 0.3, -1.2, 0.7, 10, -20, 300;
  const Rigid3d t = Rigid3d::FromMinimal(x);
  EXPECT_LT((t.ToMinimal() - x).norm(), 1e-12);
  // Translation is the plain translation, not the SE(3) twist's rho.
  EXPECT_TRUE(t.translation.isApprox(Eigen::Vector3d(10, -20, 300)));
}

}  // namespace
}  // namespace msmcal::geometry

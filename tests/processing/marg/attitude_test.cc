#include "processing/marg/attitude.h"

#include <gtest/gtest.h>

#include <random>

#include "common/units.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::marg {
namespace {

Eigen::Quaterniond RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0, 1);
  Eigen::Vector4d v(g(rng), g(rng), g(rng), g(rng));
  v.normalize();
  return Eigen::Quaterniond(v(0), v(1), v(2), v(3));
}

TEST(AttitudeTest, RecoversKnownQuaternions) {
  const AttitudeReference ref = AttitudeReference::FromElevation(common::DegToRad(-60));
  std::mt19937_64 rng(1);
  for (int k = 0; k < 50; ++k) {
    const Eigen::Quaterniond q = RandomRotation(rng);
    const Eigen::Vector3d a = q.conjugate() * ref.gravity * 0.98;  // lengths do not matter
    const Eigen::Vector3d m = q.conjugate() * ref.magnetic * 48.0;
    // From TRIAD and from a far start (identity).
    for (const auto& init :
         {std::optional<Eigen::Quaterniond>{}, std::optional(Eigen::Quaterniond::Identity())}) {
      const AttitudeSolution sol = SolveAttitude(a, m, ref, init);
      ASSERT_TRUE(sol.valid);
      EXPECT_LT(geometry::RotationDistance(sol.earth_from_body, q), 1e-9) << k;
      EXPECT_LT(sol.cost, 1e-18);
    }
  }
}

TEST(AttitudeTest, CostIsTheSquaredResidualAndMinimal) {
  const AttitudeReference ref = AttitudeReference::FromElevation(-1.0);
  std::mt19937_64 rng(2);
  const Eigen::Quaterniond q = RandomRotation(rng);
  // Inconsistent pair: the measured dip differs from the reference by 3 deg.
  const Eigen::Vector3d a = q.conjugate() * ref.gravity;
  const Eigen::Vector3d m =
      q.conjugate() * AttitudeReference::FromElevation(-1.0 + common::DegToRad(3)).magnetic;
  const AttitudeSolution sol = SolveAttitude(a, m, ref);
  ASSERT_TRUE(sol.valid);
  // Best split of a 3 deg disagreement between two unit vectors: 2 * (2 sin(0.75 deg))^2.
  const double expected = 2 * std::pow(2 * std::sin(common::DegToRad(0.75)), 2);
  EXPECT_NEAR(sol.cost, expected, 1e-9);
  // Any perturbation increases the cost.
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d(i) = 1e-3;
    const Eigen::Quaterniond p = sol.earth_from_body * Eigen::Quaterniond(geometry::So3Exp(d));
    EXPECT_GT(AttitudeCost(p, a, m, ref), sol.cost);
  }
}

TEST(AttitudeTest, EulerAnglesAndElevation) {
  const double roll = 0.1, pitch = -0.2, yaw = 2.5;
  const Eigen::Quaterniond q = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
  EXPECT_TRUE(RollPitchYaw(q).isApprox(Eigen::Vector3d(roll, pitch, yaw), 1e-12));
  const AttitudeReference ref = AttitudeReference::FromElevation(-0.9);
  EXPECT_NEAR(EstimateFieldElevation({q.conjugate() * ref.gravity}, {q.conjugate() * ref.magnetic}),
              -0.9, 1e-12);
  EXPECT_FALSE(SolveAttitude({0, 0, 1}, {0, 0, 2}, ref).valid);  // parallel: undetermined
}

}  // namespace
}  // namespace msmcal::marg

#include "processing/marg/plane_alignment.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "common/units.h"

namespace msmcal::marg {
namespace {

// A vector fixed in the world traced in a sensor frame whose z axis is `tilt` * z_board:
// v(psi) = tilt * Rz(psi) * v0.
std::vector<Eigen::Vector3d> Circle(const Eigen::Matrix3d& tilt, const Eigen::Vector3d& v0,
                                    double turn_deg, int n, double noise, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0, noise);
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i < n; ++i) {
    const double psi = common::DegToRad(turn_deg) * i / n;
    out.push_back(tilt * (Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()) * v0) +
                  Eigen::Vector3d(g(rng), g(rng), g(rng)));
  }
  return out;
}

TEST(PlaneAlignmentTest, MatrixMatchesPaperForm) {
  // Eq. 3: [cp, sp sr, sp cr; 0, cr, -sr; -sp, cp sr, cp cr].
  const double r = 0.1, p = -0.2;
  Eigen::Matrix3d expected;
  expected << std::cos(p), std::sin(p) * std::sin(r), std::sin(p) * std::cos(r), 0, std::cos(r),
      -std::sin(r), -std::sin(p), std::cos(p) * std::sin(r), std::cos(p) * std::cos(r);
  EXPECT_TRUE(AlignmentMatrix(r, p).isApprox(expected, 1e-15));
}

TEST(PlaneAlignmentTest, RecoversKnownTilt) {
  // Sensor tilted 3 deg about x then -2 deg about y relative to the board.
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(-0.035, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(0.052, Eigen::Vector3d::UnitX()))
                                   .toRotationMatrix();
  const Eigen::Vector3d v0 = Eigen::Vector3d(std::sin(0.4), 0, std::cos(0.4));  // 23 deg cone
  const auto res = FitPlaneAlignment(Circle(tilt, v0, 370, 500, 0, 1));
  ASSERT_TRUE(res.ok()) << res.message;
  const Eigen::Vector3d n_true = tilt.col(2);
  EXPECT_LT((res.normal - n_true).norm(), 1e-12);
  EXPECT_LT((res.alignment * n_true - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_NEAR(res.circle_radius / std::sqrt(2.0), std::sin(0.4) / std::sqrt(2.0), 1e-3);
  EXPECT_NEAR(res.alpha, -n_true.x() / n_true.z(), 1e-12);
  EXPECT_NEAR(res.beta, -n_true.y() / n_true.z(), 1e-12);
  EXPECT_GT(res.turn_deg, 359);
  // After alignment the traced z is constant.
  for (const auto& p : Circle(tilt, v0, 360, 50, 0, 2)) {
    EXPECT_NEAR((res.alignment * p).z(), std::cos(0.4), 1e-12);
  }

  // Noisy: 0.4 % noise, 600 samples: normal within ~0.05 deg.
  const auto noisy = FitPlaneAlignment(Circle(tilt, v0, 400, 600, 0.004, 3));
  ASSERT_TRUE(noisy.ok()) << noisy.message;
  EXPECT_LT(common::RadToDeg(std::acos(std::min(1.0, noisy.normal.dot(n_true)))), 0.1);
}

TEST(PlaneAlignmentTest, ReportsMissingCircleAndPartialTurn) {
  // Gravity on a level plane: the vector is along the rotation axis, no circle.
  auto res = FitPlaneAlignment(Circle(Eigen::Matrix3d::Identity(), {0, 0, 1}, 360, 100, 1e-4, 4));
  EXPECT_EQ(res.status, PlaneAlignmentStatus::kNoCircle) << res.message;
  EXPECT_NE(res.message.find("inclined"), std::string::npos);
  res = FitPlaneAlignment(Circle(Eigen::Matrix3d::Identity(), {0.5, 0, 0.8}, 180, 100, 0, 5));
  EXPECT_EQ(res.status, PlaneAlignmentStatus::kPartialTurn) << res.message;
  EXPECT_NEAR(res.turn_deg, 180, 2);
  res = FitPlaneAlignment({});
  EXPECT_EQ(res.status, PlaneAlignmentStatus::kTooFewSamples);
}

}  // namespace
}  // namespace msmcal::marg

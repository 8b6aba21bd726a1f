#include "processing/marg/coverage.h"

#include <gtest/gtest.h>

#include <random>

namespace msmcal::marg {
namespace {

std::vector<Eigen::Vector3d> RandomDirections(int n, uint64_t seed, bool upper_only) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0, 1);
  std::vector<Eigen::Vector3d> out;
  while (static_cast<int>(out.size()) < n) {
    Eigen::Vector3d u(g(rng), g(rng), g(rng));
    if (upper_only && u.z() < 0) continue;
    out.push_back(37.0 * u.normalized());  // any length
  }
  return out;
}

TEST(CoverageTest, FullSphereIsCovered) {
  const auto r = SphereCoverage(RandomDirections(2000, 1, false));
  EXPECT_GE(r.fraction, 0.98);
  EXPECT_LE(r.fraction, 1.0);
  EXPECT_EQ(r.counts.size(), 100u);
}

TEST(CoverageTest, HemisphereIsHalfAndListsTheMissingSide) {
  const auto r = SphereCoverage(RandomDirections(2000, 2, true));
  EXPECT_GE(r.fraction, 0.48);
  EXPECT_LE(r.fraction, 0.6);
  ASSERT_FALSE(r.missing_directions.empty());
  for (const auto& d : r.missing_directions) {
    EXPECT_LT(d.z(), 0.1) << d.transpose();
    EXPECT_NEAR(d.norm(), 1, 1e-12);
  }
  EXPECT_NE(DescribeDirection({0, 0, -1}).find("-z"), std::string::npos);
}

TEST(CoverageTest, EmptyAndSingleDirection) {
  EXPECT_EQ(SphereCoverage({}).fraction, 0);
  const auto one = SphereCoverage({Eigen::Vector3d(0, 0, 1), Eigen::Vector3d::Zero()});
  EXPECT_EQ(one.covered_cells, 1);
  EXPECT_EQ(one.missing_directions.size(), 99u);
}

TEST(CoverageTest, FibonacciCellsAreNearlyUniform) {
  const auto c = FibonacciSphere(200);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : c) sum += p;
  EXPECT_LT(sum.norm() / 200, 0.01);
}

}  // namespace
}  // namespace msmcal::marg

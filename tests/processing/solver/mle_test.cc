#include "processing/solver/mle.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>

#include "common/units.h"
#include "processing/solver/initialise.h"
#include "processing/solver/synthetic_scene.h"

namespace msmcal::solver {
namespace {

TEST(InitialMirrorPlaneTest, ExactOnNoiselessGeometry) {
  SyntheticSceneOptions o;
  o.num_planes = 5;
  const SyntheticScene s = MakeSyntheticScene(o);
  for (int j = 0; j < o.num_planes; ++j) {
    std::vector<geometry::Line> beams;
    std::vector<Eigen::Vector3d> dots;
    for (int b = 0; b < 3; ++b) {
      beams.push_back(s.truth.beams[b]);
      dots.push_back(*ReflectedPointOnWorld(s.truth.beams[b], s.truth.planes[j]));
    }
    const auto plane = InitialMirrorPlane(beams, dots);
    ASSERT_TRUE(plane);
    EXPECT_LT(geometry::AngleBetween(plane->n, s.truth.planes[j].n), 1e-9);
    EXPECT_NEAR(plane->d, s.truth.planes[j].d, 1e-7);
  }
}

TEST(InitialMirrorPlaneTest, ParallelLightPathPlanesAreRejected) {
  const geometry::Line a = geometry::Line::FromPointDirection({0, 0, 0}, {1, 0, 0});
  const geometry::Line b = geometry::Line::FromPointDirection({0, 1, 0}, {1, 0, 0});
  EXPECT_FALSE(InitialMirrorPlane({a, b}, {Eigen::Vector3d(5, 0, 1), Eigen::Vector3d(5, 1, 1)}));
}

TEST(DirectionSigmaTest, RmsAngleOfTheDirectionBlock) {
  // Closed form: sqrt(trace) of the 2x2 angle block; a slightly negative trace from rounding is 0.
  Eigen::Matrix2d c;
  c << 9e-8, 5e-8, 5e-8, 16e-8;
  EXPECT_DOUBLE_EQ(DirectionSigmaRad(c), 5e-4);
  EXPECT_EQ(DirectionSigmaRad(Eigen::Matrix2d::Identity() * -1e-20), 0.0);

  // Beam b's block sits at OffsetBeam(b) = 12 + 6 * num_poses + 4 * b of other_cov.
  MleResult m;
  m.num_poses = 2;
  const int n = 12 + 6 * 2 + 4 * 2;  // two beams
  m.other_cov = Eigen::MatrixXd::Identity(n, n);
  m.other_cov.block<2, 2>(m.OffsetBeam(1), m.OffsetBeam(1)) = c;
  EXPECT_DOUBLE_EQ(m.BeamDirectionSigmaRad(0), std::sqrt(2.0));
  EXPECT_DOUBLE_EQ(m.BeamDirectionSigmaRad(1), 5e-4);
  EXPECT_TRUE(std::isnan(m.BeamDirectionSigmaRad(2)));  // not in the covariance
  EXPECT_TRUE(std::isnan(m.BeamDirectionSigmaRad(-1)));
  EXPECT_TRUE(std::isnan(MleResult{}.BeamDirectionSigmaRad(0)));  // no covariance at all
}

TEST(ChartTest, PlaneChartRoundTrip) {
  const geometry::Plane ref{Eigen::Vector3d(0.3, -0.2, 0.9).normalized(), 12.0};
  const Eigen::Vector3d x(0.01, -0.02, 0.3);
  const geometry::Plane p = PlaneFromChart(ref, x);
  EXPECT_LT((PlaneToChart(ref, p) - x).norm(), 1e-12);
}

TEST(SolveMleTest, RecoversTruthFromNoisyObservations) {
  SyntheticSceneOptions o;
  o.num_planes = 30;
  o.seed = 7;
  const SyntheticScene s = MakeSyntheticScene(o);
  std::string err;
  const auto init = InitialEstimate(s.obs, &err);
  ASSERT_TRUE(init) << err;
  const MleResult r = SolveMle(s.obs, *init);
  ASSERT_TRUE(r.usable) << r.message;
  for (int b = 0; b < s.obs.num_beams; ++b) {
    // Estimate beams are constrained by the reflections too; the held-out beam only by its
    // sliding-plane dots.
    const double tol_deg = b < o.num_estimate ? 0.01 : 0.05;
    EXPECT_LT(
        geometry::AngleBetween(r.estimate.beams[b].v, s.truth.beams[b].v) * common::kDegPerRad,
        tol_deg)
        << "beam " << b;
    EXPECT_LT(geometry::LineLineDistance(r.estimate.beams[b], s.truth.beams[b]), 0.05);
  }
  double sum2 = 0;
  for (int j = 0; j < o.num_planes; ++j) {
    const double e = geometry::AngleBetween(r.estimate.planes[j].n, s.truth.planes[j].n);
    sum2 += e * e;
    EXPECT_NEAR(r.estimate.planes[j].d, s.truth.planes[j].d, 0.3) << "plane " << j;
  }
  EXPECT_LT(std::sqrt(sum2 / o.num_planes) * common::kDegPerRad, 0.05);
  // Variance factors near 1: the simulated covariances are the true ones.
  EXPECT_NEAR(r.dot_variance_factor, 1.0, 0.3);
  EXPECT_NEAR(r.corner_variance_factor, 1.0, 0.3);
}

// Normalised errors (error / predicted sigma) must have unit RMS within +-25 % over many seeds.
TEST(SolveMleTest, PlaneCovarianceIsHonest) {
  Eigen::Vector3d sum2 = Eigen::Vector3d::Zero();
  int n = 0;
  for (uint64_t seed = 1; seed <= 30; ++seed) {
    SyntheticSceneOptions o;
    o.num_planes = 8;
    o.num_poses = 4;
    o.seed = seed;
    const SyntheticScene s = MakeSyntheticScene(o);
    std::string err;
    const auto init = InitialEstimate(s.obs, &err);
    ASSERT_TRUE(init) << err;
    const MleResult r = SolveMle(s.obs, *init);
    ASSERT_TRUE(r.usable) << r.message;
    for (int j = 0; j < o.num_planes; ++j) {
      const Eigen::Vector3d e = PlaneToChart(r.estimate.planes[j], s.truth.planes[j]);
      for (int k = 0; k < 3; ++k) sum2(k) += e(k) * e(k) / r.plane_cov[j](k, k);
      ++n;
    }
  }
  const Eigen::Vector3d rms = (sum2 / n).cwiseSqrt();
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(rms(k), 0.75) << "component " << k;
    EXPECT_LT(rms(k), 1.25) << "component " << k;
  }
}

}  // namespace
}  // namespace msmcal::solver

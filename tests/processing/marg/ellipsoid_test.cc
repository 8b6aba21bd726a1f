#include "processing/marg/ellipsoid.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "common/units.h"

namespace msmcal::marg {
namespace {

struct TrueEllipsoid {
  Eigen::Vector3d centre;
  Eigen::Matrix3d rotation;
  Eigen::Vector3d semi_axes;
  // Point on the surface for unit direction u: c + R diag(s) u.
  Eigen::Vector3d Point(const Eigen::Vector3d& u) const {
    return centre + rotation * semi_axes.asDiagonal() * u;
  }
  Eigen::Matrix3d Shape() const {
    return rotation * semi_axes.cwiseInverse().cwiseAbs2().asDiagonal() * rotation.transpose();
  }
};

TrueEllipsoid MakeEllipsoid(const Eigen::Vector3d& centre, const Eigen::Vector3d& semi_axes) {
  TrueEllipsoid e;
  e.centre = centre;
  e.semi_axes = semi_axes;
  e.rotation = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  return e;
}

std::vector<Eigen::Vector3d> Sample(const TrueEllipsoid& e, int n, double noise, uint64_t seed,
                                    double max_polar_rad = M_PI) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0, 1);
  std::vector<Eigen::Vector3d> out;
  while (static_cast<int>(out.size()) < n) {
    Eigen::Vector3d u(g(rng), g(rng), g(rng));
    u.normalize();
    if (std::acos(u.z()) > max_polar_rad) continue;
    out.push_back(e.Point(u) + noise * Eigen::Vector3d(g(rng), g(rng), g(rng)));
  }
  return out;
}

TEST(QuadricTest, MatrixFormMatchesAlgebraicForm) {
  QuadricCoefficients q{1.5, 2, 3, 0.4, -0.2, 0.3, 1, -2, 0.5, -7};
  const Eigen::Vector3d p(0.3, -1.2, 2.0);
  const Eigen::Vector4d x(p.x(), p.y(), p.z(), 1);
  EXPECT_NEAR(x.dot(QuadricMatrix(q) * x), EvaluateQuadric(q, p), 1e-12);
}

TEST(QuadricTest, EllipsoidQuadricRoundTrip) {
  const TrueEllipsoid t = MakeEllipsoid({1, -2, 3}, {5, 3, 2});
  Ellipsoid e;
  ASSERT_TRUE(Ellipsoid::FromCentreShape(t.centre, t.Shape(), &e));
  const QuadricCoefficients q = QuadricFromEllipsoid(e);
  // Points on the surface satisfy eq. 4.
  for (const auto& p : Sample(t, 20, 0, 1)) EXPECT_NEAR(EvaluateQuadric(q, p), 0, 1e-12);
  Ellipsoid back;
  std::string why;
  ASSERT_TRUE(EllipsoidFromQuadric(q, &back, &why)) << why;
  EXPECT_TRUE(back.centre.isApprox(t.centre, 1e-12));
  EXPECT_TRUE(back.shape.isApprox(t.Shape(), 1e-12));
  EXPECT_NEAR(back.semi_axes(0), 5, 1e-12);
  EXPECT_NEAR(back.semi_axes(2), 2, 1e-12);
  EXPECT_NEAR(back.axes.determinant(), 1, 1e-12);
  // A = W^(1/2) maps the surface onto the unit sphere.
  for (const auto& p : Sample(t, 20, 0, 2)) EXPECT_NEAR(back.RadialResidual(p), 0, 1e-12);
  // Scaling the quadric does not change the ellipsoid; a hyperboloid is rejected.
  QuadricCoefficients hyper{1, 1, -1, 0, 0, 0, 0, 0, 0, -1};
  EXPECT_FALSE(EllipsoidFromQuadric(hyper, &back, &why));
  EXPECT_NE(why.find("not definite"), std::string::npos) << why;
}

TEST(EllipsoidFitTest, RecoversNoiseFreeEllipsoidExactly) {
  const TrueEllipsoid t = MakeEllipsoid({10, -5, 3}, {50, 40, 30});
  const auto fit = FitEllipsoid(Sample(t, 400, 0, 3));
  ASSERT_TRUE(fit.ok()) << fit.message;
  EXPECT_LT((fit.ellipsoid.centre - t.centre).norm(), 1e-8);
  EXPECT_LT((fit.ellipsoid.shape - t.Shape()).norm() / t.Shape().norm(), 1e-9);
  EXPECT_LT((fit.algebraic_ellipsoid.centre - t.centre).norm(), 1e-8);  // exact before refining
  EXPECT_EQ(fit.num_inliers, 400);
  EXPECT_LT(fit.rms_radial_residual, 1e-10);
}

TEST(EllipsoidFitTest, RecoversNoisyEllipsoidWithinTolerance) {
  const TrueEllipsoid t = MakeEllipsoid({10, -5, 3}, {50, 40, 30});
  const double noise = 0.4;  // ~1 % of the radius
  const auto fit = FitEllipsoid(Sample(t, 2000, noise, 4));
  ASSERT_TRUE(fit.ok()) << fit.message;
  // Centre and semi-axes to a small fraction of the noise (2000 samples).
  EXPECT_LT((fit.ellipsoid.centre - t.centre).norm(), 0.1);
  EXPECT_NEAR(fit.ellipsoid.semi_axes(0), 50, 0.1);
  EXPECT_NEAR(fit.ellipsoid.semi_axes(1), 40, 0.1);
  EXPECT_NEAR(fit.ellipsoid.semi_axes(2), 30, 0.1);
  EXPECT_NEAR(fit.rms_radial_residual, noise / 40, 0.004);
}

TEST(EllipsoidFitTest, BadlyScaledEllipsoidWithLargeOffset) {
  // Hard-iron offsets of thousands of uT around a ~50 uT field: without normalisation the
  // algebraic system's condition is ~1e16.
  const TrueEllipsoid t = MakeEllipsoid({3000, -2500, 4000}, {55, 48, 41});
  const auto exact = FitEllipsoid(Sample(t, 300, 0, 5));
  ASSERT_TRUE(exact.ok()) << exact.message;
  EXPECT_LT((exact.ellipsoid.centre - t.centre).norm(), 1e-6);
  EXPECT_LT((exact.ellipsoid.shape - t.Shape()).norm() / t.Shape().norm(), 1e-8);

  const auto noisy = FitEllipsoid(Sample(t, 2000, 0.3, 6));
  ASSERT_TRUE(noisy.ok()) << noisy.message;
  EXPECT_LT((noisy.ellipsoid.centre - t.centre).norm(), 0.1);
  EXPECT_NEAR(noisy.ellipsoid.semi_axes(0), 55, 0.1);
  EXPECT_NEAR(noisy.ellipsoid.semi_axes(2), 41, 0.1);
}

TEST(EllipsoidFitTest, GeometricRefinementReducesAlgebraicBias) {
  // Strong noise on a flattened ellipsoid: the algebraic fit is biased; the radial refinement
  // must be at least as close to the truth.
  const TrueEllipsoid t = MakeEllipsoid({0, 0, 0}, {50, 30, 20});
  const auto fit = FitEllipsoid(Sample(t, 3000, 2.0, 7));
  ASSERT_TRUE(fit.ok()) << fit.message;
  const double alg = (fit.algebraic_ellipsoid.semi_axes - t.semi_axes).norm();
  const double geo = (fit.ellipsoid.semi_axes - t.semi_axes).norm();
  EXPECT_LE(geo, alg + 1e-9);
  EXPECT_LT(geo, 1.0);
}

TEST(EllipsoidFitTest, ReportsDegenerateSamples) {
  const TrueEllipsoid t = MakeEllipsoid({1, 2, 3}, {50, 40, 30});
  // All samples on one plane (a single turn about one axis).
  std::vector<Eigen::Vector3d> planar;
  for (int i = 0; i < 100; ++i) {
    const double a = 2 * M_PI * i / 100;
    planar.push_back(t.Point({std::cos(a), std::sin(a), 0}));
  }
  auto fit = FitEllipsoid(planar);
  EXPECT_EQ(fit.status, EllipsoidFitStatus::kDegenerate) << fit.message;
  EXPECT_NE(fit.message.find("plane"), std::string::npos) << fit.message;

  // A 10 degree cap with noise: the ellipsoid is not determined.
  fit = FitEllipsoid(Sample(t, 500, 0.3, 8, common::DegToRad(10)));
  EXPECT_EQ(fit.status, EllipsoidFitStatus::kDegenerate) << fit.message;
  EXPECT_NE(fit.message.find("condition"), std::string::npos) << fit.message;

  // Too few samples and non-finite values.
  fit = FitEllipsoid(Sample(t, 5, 0, 9));
  EXPECT_EQ(fit.status, EllipsoidFitStatus::kTooFewSamples);
  auto bad = Sample(t, 50, 0, 10);
  bad[3].x() = std::nan("");
  EXPECT_EQ(FitEllipsoid(bad).status, EllipsoidFitStatus::kNonFinite);
}

TEST(EllipsoidFitTest, ReportsNonEllipsoidSurface) {
  // Samples on a hyperboloid of one sheet x^2 + y^2 - z^2 / 4 = 1 scaled by 40.
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 40; ++i) {
    for (int j = -5; j <= 5; ++j) {
      const double a = 2 * M_PI * i / 40, h = j * 0.3;
      const double r = std::sqrt(1 + h * h / 4);
      pts.push_back(40 * Eigen::Vector3d(r * std::cos(a), r * std::sin(a), h));
    }
  }
  const auto fit = FitEllipsoid(pts);
  EXPECT_EQ(fit.status, EllipsoidFitStatus::kNotEllipsoid) << fit.message;
}

TEST(EllipsoidFitTest, RejectsOutliers) {
  const TrueEllipsoid t = MakeEllipsoid({20, -10, 35}, {52, 47, 45});
  Ellipsoid truth;
  ASSERT_TRUE(Ellipsoid::FromCentreShape(t.centre, t.Shape(), &truth));
  auto pts = Sample(t, 1000, 0.15, 11);
  std::mt19937_64 rng(12);
  std::normal_distribution<double> g(0, 1);
  std::vector<bool> spiked(pts.size(), false);
  for (size_t i = 0; i < pts.size(); i += 20) {  // 5 % spikes of ~30 uT
    pts[i] += 30 * Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    spiked[i] = true;
  }
  EllipsoidFitOptions no_rejection;
  no_rejection.max_outlier_rounds = 0;
  const auto naive = FitEllipsoid(pts, no_rejection);
  const auto fit = FitEllipsoid(pts);
  ASSERT_TRUE(fit.ok()) << fit.message;
  for (size_t i = 0; i < pts.size(); ++i) {
    // A spike that happens to land near the surface cannot be told apart; any other is
    // rejected (> 8 sigma off the surface).
    if (spiked[i] && std::abs(truth.RadialResidual(pts[i])) > 8 * 0.15 / 45) {
      EXPECT_FALSE(fit.inlier[i]) << i;
    }
  }
  EXPECT_GT(fit.num_inliers, 930) << fit.message;
  EXPECT_LT((fit.ellipsoid.centre - t.centre).norm(), 0.1);
  EXPECT_LT((fit.ellipsoid.semi_axes - t.semi_axes).norm(), 0.1);
  EXPECT_GT((naive.ellipsoid.semi_axes - t.semi_axes).norm(), 0.3);
}

TEST(EllipsoidFitTest, InvalidOptionsThrowNamingTheField) {
  EllipsoidFitOptions o;
  o.outlier_sigmas = -1;
  EXPECT_NE(o.Validate().find("outlier_sigmas=-1"), std::string::npos);
  EXPECT_THROW(FitEllipsoid({}, o), std::invalid_argument);
}

}  // namespace
}  // namespace msmcal::marg

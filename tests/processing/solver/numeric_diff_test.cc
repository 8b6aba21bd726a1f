#include "processing/solver/numeric_diff.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>

namespace msmcal::solver {
namespace {

// f(x) = [sin(x0) x1, x0^2 + exp(x1), x2^3, x0 x1 x2] and its closed-form Jacobian.
Eigen::Vector4d F(const Eigen::Vector3d& x) {
  return {std::sin(x(0)) * x(1), x(0) * x(0) + std::exp(x(1)), x(2) * x(2) * x(2),
          x(0) * x(1) * x(2)};
}
Eigen::Matrix<double, 4, 3> ClosedForm(const Eigen::Vector3d& x) {
  Eigen::Matrix<double, 4, 3> j;
  j << std::cos(x(0)) * x(1), std::sin(x(0)), 0,  //
      2 * x(0), std::exp(x(1)), 0,                //
      0, 0, 3 * x(2) * x(2),                      //
      x(1) * x(2), x(0) * x(2), x(0) * x(1);
  return j;
}

TEST(CentralDifferenceJacobian, MatchesTheClosedFormJacobian) {
  const Eigen::Vector3d x(0.3, -0.7, 1.9);
  const Eigen::Matrix<double, 4, 3> j = CentralDifferenceJacobian(F, x, kCentralDifferenceStep);
  // Truncation ~ step^2 |f'''| ~ 1e-11, rounding ~ eps |f| / step ~ 1e-10.
  EXPECT_LT((j - ClosedForm(x)).cwiseAbs().maxCoeff(), 1e-8) << j << "\n\n" << ClosedForm(x);
}

TEST(CentralDifferenceJacobian, DynamicSizesAndOrderOfEvaluation) {
  Eigen::VectorXd x(2);
  x << 1.5, -2.0;
  int calls = 0;
  std::vector<double> seen;
  auto f = [&](const Eigen::VectorXd& v) {
    ++calls;
    seen.push_back(v(0) - 1.5 + v(1) + 2.0);  // the perturbation
    Eigen::VectorXd y(3);
    y << v(0) * v(1), v(0), 2 * v(1);
    return y;
  };
  const Eigen::MatrixXd j = CentralDifferenceJacobian(f, x, 1e-3);
  ASSERT_EQ(j.rows(), 3);
  ASSERT_EQ(j.cols(), 2);
  Eigen::MatrixXd expected(3, 2);
  expected << -2.0, 1.5, 1, 0, 0, 2;
  EXPECT_LT((j - expected).cwiseAbs().maxCoeff(), 1e-9);  // exact for quadratics
  EXPECT_EQ(calls, 4);
  ASSERT_EQ(seen.size(), 4u);
  EXPECT_NEAR(seen[0], 1e-3, 1e-12);  // + then - for each coordinate in order
  EXPECT_NEAR(seen[1], -1e-3, 1e-12);
  EXPECT_NEAR(seen[2], 1e-3, 1e-12);
  EXPECT_NEAR(seen[3], -1e-3, 1e-12);
}

}  // namespace
}  // namespace msmcal::solver

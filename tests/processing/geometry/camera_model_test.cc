#include "processing/geometry/camera_model.h"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace msmcal::geometry {
namespace {

CameraModel TestCamera() {
  CameraModel c;
  c.width = 2448;
  c.height = 2048;
  c.fx = 3500;
  c.fy = 3510;
  c.cx = 1230.5;
  c.cy = 1019.25;
  c.distortion = {-0.12, 0.08, 0.0007, -0.0004, -0.02};
  return c;
}

TEST(CameraModel, MatchesOpenCvProjectPoints) {
  const CameraModel c = TestCamera();
  std::vector<cv::Point3d> pts;
  for (double x = -150; x <= 150; x += 50)
    for (double y = -120; y <= 120; y += 40) pts.emplace_back(x, y, 500 + 0.3 * x);
  std::vector<cv::Point2d> cv_px;
  cv::Mat k;
  cv::eigen2cv(c.K(), k);
  cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k,
                    std::vector<double>(c.distortion.begin(), c.distortion.end()), cv_px);
  for (size_t i = 0; i < pts.size(); ++i) {
    const auto px = c.Project(Eigen::Vector3d(pts[i].x, pts[i].y, pts[i].z));
    ASSERT_TRUE(px);
    EXPECT_NEAR(px->x(), cv_px[i].x, 1e-9);
    EXPECT_NEAR(px->y(), cv_px[i].y, 1e-9);
  }
}

TEST(CameraModel, UnprojectInvertsProject) {
  const CameraModel c = TestCamera();
  for (int u = 0; u < c.width; u += 301) {
    for (int v = 0; v < c.height; v += 257) {
      const Eigen::Vector2d px(u, v);
      const Eigen::Vector3d ray = c.Unproject(px);
      EXPECT_NEAR(ray.norm(), 1.0, 1e-12);
      const auto back = c.Project(ray * 700.0);
      ASSERT_TRUE(back);
      EXPECT_LT((*back - px).norm(), 1e-8) << u << "," << v;
    }
  }
  EXPECT_FALSE(c.Project(Eigen::Vector3d(0, 0, -1)));
}

TEST(CameraModel, AnalyticJacobianMatchesFiniteDifferences) {
  const CameraModel c = TestCamera();
  const Eigen::Vector3d p(60, -45, 480);
  const Eigen::Matrix<double, 2, 3> j = c.ProjectJacobian(p);
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d dp = Eigen::Vector3d::Zero();
    dp(k) = 1e-4;
    const Eigen::Vector2d num = (*c.Project(p + dp) - *c.Project(p - dp)) / 2e-4;
    EXPECT_LT((num - j.col(k)).norm(), 1e-5);
  }
}

TEST(CameraModel, ValidateNamesTheField) {
  CameraModel c = TestCamera();
  EXPECT_EQ(c.Validate(), "");
  c.fx = 0;
  EXPECT_NE(c.Validate().find("fx"), std::string::npos);
  c = TestCamera();
  c.width = 0;
  EXPECT_NE(c.Validate().find("image_size"), std::string::npos);
}

}  // namespace
}  // namespace msmcal::geometry

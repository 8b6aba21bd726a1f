#pragma once
// The OpenCV pinhole camera with radial-tangential distortion (k1 k2 p1 p2 k3).
// Pixel (0, 0) is the centre of the top-left pixel (OpenCV's and the interchange format's
// convention). Points are in the camera frame {C}, millimetres, Z forward.

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>

namespace msmcal::geometry {

struct CameraModel {
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::array<double, 5> distortion{};  // k1 k2 p1 p2 k3

  Eigen::Matrix3d K() const;
  // Empty string if usable, else what is wrong (names the field).
  std::string Validate() const;

  // Normalised image coordinates (x/z, y/z) -> distorted normalised coordinates.
  template <typename T>
  static void Distort(const T* dist, const T& x, const T& y, T* xd, T* yd) {
    const T r2 = x * x + y * y;
    const T radial = T(1) + r2 * (dist[0] + r2 * (dist[1] + r2 * dist[4]));
    *xd = x * radial + T(2) * dist[2] * x * y + dist[3] * (r2 + T(2) * x * x);
    *yd = y * radial + dist[2] * (r2 + T(2) * y * y) + T(2) * dist[3] * x * y;
  }

  // Projection of a point in {C}; templated for Ceres autodiff. intrinsics = fx fy cx cy,
  // dist = k1 k2 p1 p2 k3.
  template <typename T>
  static void ProjectWith(const T* intrinsics, const T* dist, const T* p_in_cam, T* pixel) {
    const T x = p_in_cam[0] / p_in_cam[2];
    const T y = p_in_cam[1] / p_in_cam[2];
    T xd, yd;
    Distort(dist, x, y, &xd, &yd);
    pixel[0] = intrinsics[0] * xd + intrinsics[2];
    pixel[1] = intrinsics[1] * yd + intrinsics[3];
  }

  // Pixel of a point in {C}. Points behind the camera (z <= 0) give empty.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_in_cam) const;
  // Normalised, undistorted coordinates (x/z, y/z) of a pixel (iterative inverse of the
  // distortion; accurate to 1e-12 over the image for realistic distortion).
  Eigen::Vector2d Undistort(const Eigen::Vector2d& pixel) const;
  // Unit ray in {C} through a pixel.
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel) const;
  // 2x3 Jacobian of Project with respect to the point in {C} (analytic).
  Eigen::Matrix<double, 2, 3> ProjectJacobian(const Eigen::Vector3d& p_in_cam) const;
};

}  // namespace msmcal::geometry

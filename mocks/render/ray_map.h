#pragma once
// Per-pixel ray map of a camera: the undistorted normalised coordinates (x/z, y/z) of the ray
// through every pixel centre. Computing it inverts the distortion once per pixel, so the
// renderer caches it per camera (CachedRayMap) and repeated frames only read it.

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "processing/geometry/camera_model.h"

namespace msmcal::render {

class RayMap {
 public:
  // Throws std::invalid_argument if the camera does not validate or is smaller than 2x2 px.
  // Cost: one Newton inversion of the distortion per pixel (warm-started from the neighbour).
  explicit RayMap(const geometry::CameraModel& cam);

  int width() const { return cam_.width; }
  int height() const { return cam_.height; }
  const geometry::CameraModel& camera() const { return cam_; }

  // Row y: 2 * width floats, interleaved (u, v) per pixel; the ray in {C} is (u, v, 1).
  const float* Row(int y) const { return uv_.data() + 2 * static_cast<size_t>(y) * cam_.width; }
  Eigen::Vector2d At(int x, int y) const {
    const float* p = Row(y) + 2 * x;
    return {p[0], p[1]};
  }
  // d(u, v)/d(pixel x, pixel y) at pixel (x, y) by central differences of the map (one-sided
  // at the image border). Column 0 is d/dx, column 1 is d/dy.
  Eigen::Matrix2d Jacobian(int x, int y) const;

  // True if `cam` has exactly the parameters this map was built for.
  bool Matches(const geometry::CameraModel& cam) const;

  // Largest |distort(u, v) - target| left by the inversion, in normalised units (diagnostic).
  double max_residual() const { return max_residual_; }

 private:
  geometry::CameraModel cam_;
  std::vector<float> uv_;
  double max_residual_ = 0.0;
};

// The ray map of `cam` from a small process-wide cache (the most recently used cameras), built
// on a miss. Thread-safe; the returned map is immutable and stays valid while held.
std::shared_ptr<const RayMap> CachedRayMap(const geometry::CameraModel& cam);

}  // namespace msmcal::render

#include "mocks/render/ray_map.h"

#include <algorithm>
#include <cmath>
#include <list>
#include <mutex>
#include <stdexcept>

namespace msmcal::render {
namespace {

// Newton inversion of CameraModel::Distort with the analytic 2x2 Jacobian. Returns the
// remaining residual norm; `u` holds the start on entry and the solution on exit.
double InvertDistortion(const std::array<double, 5>& dist, double tx, double ty, double* u,
                        double* v) {
  const double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3], k3 = dist[4];
  double x = *u, y = *v;
  double res = 0.0;
  for (int it = 0; it < 30; ++it) {
    const double r2 = x * x + y * y;
    const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dradial = k1 + 2 * k2 * r2 + 3 * k3 * r2 * r2;
    const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
    const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
    const double ex = xd - tx, ey = yd - ty;
    res = std::sqrt(ex * ex + ey * ey);
    if (res < 1e-15) break;
    const double a = radial + x * dradial * 2 * x + 2 * p1 * y + p2 * 6 * x;
    const double b = x * dradial * 2 * y + 2 * p1 * x + p2 * 2 * y;
    const double c = y * dradial * 2 * x + p1 * 2 * x + 2 * p2 * y;
    const double d = radial + y * dradial * 2 * y + p1 * 6 * y + 2 * p2 * x;
    const double det = a * d - b * c;
    if (!(std::abs(det) > 1e-300)) break;
    const double sx = (d * ex - b * ey) / det;
    const double sy = (-c * ex + a * ey) / det;
    x -= sx;
    y -= sy;
    if (std::abs(sx) + std::abs(sy) < 1e-16) break;  // step below double resolution
  }
  *u = x;
  *v = y;
  return res;
}

}  // namespace

RayMap::RayMap(const geometry::CameraModel& cam) : cam_(cam) {
  const std::string err = cam.Validate();
  if (!err.empty()) throw std::invalid_argument("RayMap: invalid camera: " + err);
  if (cam.width < 2 || cam.height < 2)
    throw std::invalid_argument("RayMap: camera image_size must be at least 2x2 px, got [" +
                                std::to_string(cam.width) + ", " + std::to_string(cam.height) +
                                "]");
  const int w = cam.width, h = cam.height;
  uv_.resize(2 * static_cast<size_t>(w) * h);
  double row_u = (0 - cam.cx) / cam.fx, row_v = (0 - cam.cy) / cam.fy;
  for (int y = 0; y < h; ++y) {
    float* out = uv_.data() + 2 * static_cast<size_t>(y) * w;
    const double ty = (y - cam.cy) / cam.fy;
    // Warm start: the solutions at x-1 and x-2 extrapolated linearly, so that one Newton step
    // reaches double precision.
    double u1 = row_u, v1 = row_v;  // solution at x-1
    double u2 = row_u, v2 = row_v;  // solution at x-2
    for (int x = 0; x < w; ++x) {
      const double tx = (x - cam.cx) / cam.fx;
      double u = x >= 2 ? 2 * u1 - u2 : u1, v = x >= 2 ? 2 * v1 - v2 : v1;
      double res = InvertDistortion(cam.distortion, tx, ty, &u, &v);
      if (!(res < 1e-10)) {  // Warm start failed (strong distortion): start from the target.
        u = tx;
        v = ty;
        res = InvertDistortion(cam.distortion, tx, ty, &u, &v);
      }
      max_residual_ = std::max(max_residual_, std::isfinite(res) ? res : 1e300);
      out[2 * x] = static_cast<float>(u);
      out[2 * x + 1] = static_cast<float>(v);
      if (x == 0) {
        row_u = u;
        row_v = v;
      }
      u2 = u1;
      v2 = v1;
      u1 = u;
      v1 = v;
    }
  }
}

Eigen::Matrix2d RayMap::Jacobian(int x, int y) const {
  const int w = cam_.width, h = cam_.height;
  const int x0 = std::max(x - 1, 0), x1 = std::min(x + 1, w - 1);
  const int y0 = std::max(y - 1, 0), y1 = std::min(y + 1, h - 1);
  Eigen::Matrix2d j;
  j.col(0) = (At(x1, y) - At(x0, y)) / static_cast<double>(x1 - x0);
  j.col(1) = (At(x, y1) - At(x, y0)) / static_cast<double>(y1 - y0);
  return j;
}

bool RayMap::Matches(const geometry::CameraModel& c) const {
  return c.width == cam_.width && c.height == cam_.height && c.fx == cam_.fx && c.fy == cam_.fy &&
         c.cx == cam_.cx && c.cy == cam_.cy && c.distortion == cam_.distortion;
}

std::shared_ptr<const RayMap> CachedRayMap(const geometry::CameraModel& cam) {
  // A 10 MP map is 80 MB: keep only the two most recently used cameras (e.g. the two cameras
  // of a simulated rig).
  constexpr size_t kCapacity = 2;
  static std::mutex mutex;
  static std::list<std::shared_ptr<const RayMap>> cache;  // front = most recently used
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (auto it = cache.begin(); it != cache.end(); ++it) {
      if ((*it)->Matches(cam)) {
        cache.splice(cache.begin(), cache, it);
        return cache.front();
      }
    }
  }
  // Build outside the lock: another thread may build the same map concurrently; both results
  // are identical, and the cache keeps one.
  auto map = std::make_shared<const RayMap>(cam);
  std::lock_guard<std::mutex> lock(mutex);
  for (auto& m : cache)
    if (m->Matches(cam)) return m;
  cache.push_front(map);
  while (cache.size() > kCapacity) cache.pop_back();
  return map;
}

}  // namespace msmcal::render

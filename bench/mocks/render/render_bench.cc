// Speed of the rig simulator's renderer on a 10 MP frame (3840 x 2748): two boards (world
// plane and sliding plate, occluding) and 6 laser dots, default noise and PSF. Single thread.
// Run: build-*/bench/mocks/render/render_bench

#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <numbers>

#include "common/units.h"
#include "mocks/render/ray_map.h"
#include "mocks/render/renderer.h"

namespace msmcal::render {
namespace {

geometry::CameraModel TenMegapixelCamera() {
  geometry::CameraModel cam;
  cam.width = 3840;
  cam.height = 2748;
  cam.fx = 4200;
  cam.fy = 4202;
  cam.cx = 1921.7;
  cam.cy = 1372.2;
  cam.distortion = {-0.12, 0.05, 0.0007, -0.0004, 0.0};
  return cam;
}

SceneBoard Board(const BoardSpec& spec, const Eigen::Vector3d& centre, double tilt_deg,
                 const Eigen::Vector3d& axis) {
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(common::DegToRad(tilt_deg), axis.normalized()).toRotationMatrix();
  const Eigen::Vector3d c(0.5 * (spec.cols - 1) * spec.square_mm,
                          0.5 * (spec.rows - 1) * spec.square_mm, 0);
  return SceneBoard{spec, geometry::Rigid3d(r, centre - r * c)};
}

std::vector<SceneBoard> Boards() {
  return {Board({15, 10, 30.0, 1.0}, {0, 0, 900}, 20, Eigen::Vector3d::UnitY()),    // world plane
          Board({9, 6, 15.0, 1.0}, {-60, 30, 550}, 35, Eigen::Vector3d(1, 1, 0))};  // sliding
}

std::vector<SceneDot> Dots() {
  std::vector<SceneDot> dots;
  for (int k = 0; k < 6; ++k) {
    SceneDot d;
    d.p_in_cam = {-250.0 + 100 * k, -80.0 + 30 * k, 880.0 - 10 * k};
    d.sigma_mm = 0.6;
    d.normal_in_cam = {0.3, 0, -1};
    d.peak = k == 0 ? 3.0 : 0.7;  // one saturated dot
    dots.push_back(d);
  }
  return dots;
}

void BM_Render10MP(benchmark::State& state) {
  const geometry::CameraModel cam = TenMegapixelCamera();
  RenderOptions opt;
  opt.format = static_cast<PixelFormat>(state.range(0));
  opt.blur_sigma_px = state.range(1) / 10.0;
  cv::Mat out(cam.height, cam.width, CvType(opt.format));
  const auto boards = Boards();
  const auto dots = Dots();
  CachedRayMap(cam);  // built once per camera, outside the timing
  RenderStats stats;
  for (auto _ : state) {
    RenderInto(cam, boards, dots, opt, out, &stats);
    benchmark::DoNotOptimize(out.data);
    ++opt.seed;
  }
  state.SetLabel(std::string(ToString(opt.format)) + " blur " + std::to_string(opt.blur_sigma_px));
  state.counters["edge_px"] = static_cast<double>(stats.edge_pixels);
  state.counters["outline_px"] = static_cast<double>(stats.outline_pixels);
  state.counters["Mpx/s"] = benchmark::Counter(static_cast<double>(cam.width) * cam.height / 1e6,
                                               benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Render10MP)
    ->Args({static_cast<int>(PixelFormat::kMono8), 8})
    ->Args({static_cast<int>(PixelFormat::kBgr8), 8})
    ->Args({static_cast<int>(PixelFormat::kMono16), 8})
    ->Args({static_cast<int>(PixelFormat::kMono8), 0})
    ->Unit(benchmark::kMillisecond);

void BM_RayMap10MP(benchmark::State& state) {
  const geometry::CameraModel cam = TenMegapixelCamera();
  for (auto _ : state) {
    RayMap map(cam);
    benchmark::DoNotOptimize(map.Row(0));
  }
}
BENCHMARK(BM_RayMap10MP)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace
}  // namespace msmcal::render

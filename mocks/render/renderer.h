#pragma once
// Image renderer of the rig simulator: checkerboards and laser dots seen by a distorted pinhole
// camera (processing/geometry/camera_model.h). A pure function of its inputs and a seed: no
// I/O, no clocks, no global state except a thread-safe cache of per-camera ray maps.
//
// Physics, per pixel: the ray through the pixel (distortion inverted exactly, see ray_map.h)
// hits the nearest board (occlusion); the pixel value is the area average of that board's
// reflectance over the pixel footprint (exact polygon clipping of the footprint against the
// squares for pixels crossed by a square edge; S x S supersampling for pixels crossed by a
// board's outline; flat elsewhere), then blurred by the optics' PSF (Gaussian). Laser dots are
// Gaussians centred at the projected dot, added on top; then photon-like noise (seeded),
// clipping at full scale and quantisation.
//
// Board convention (docs/interchange-format.md): board frame origin at the origin inner
// corner, X along cols, Y along rows, Z = X x Y pointing into the board (away from the printed
// side). Inner corner (c, r) is at (c * square_mm, r * square_mm, 0). The square whose minimum
// corner is inner corner (i, j), i in [-1, cols-1], j in [-1, rows-1], is dark iff (i + j) is
// even. White margin of margin_squares squares around the outer squares.
//
// Levels are fractions of full scale (1.0 = 255 in Mono8/Bgr8, 65535 in Mono16).
// Thread safety: Render/RenderInto may run concurrently on different outputs.
// Cost (single thread): the first frame of a camera builds its ray map (10 MP: ~0.4 s, 84 MB,
// kept for the two most recently used cameras); later 10 MP frames take ~0.2-0.3 s
// (bench/mocks/render/render_bench).
// Limits: boards must not interpenetrate in view (their intersection line is not
// anti-aliased); footprints are treated as affine (exact to ~1e-4 px).

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "processing/geometry/camera_model.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::render {

enum class PixelFormat { kMono8, kMono16, kBgr8 };
// CV_8UC1, CV_16UC1 or CV_8UC3 (BGR order).
int CvType(PixelFormat format);
const char* ToString(PixelFormat format);

struct BoardSpec {
  int cols = 9;  // inner corners along X
  int rows = 6;  // inner corners along Y
  double square_mm = 10.0;
  double margin_squares = 1.0;  // white border beyond the outer squares, in squares
  // Empty if usable, else the field, its value and the violated constraint.
  std::string Validate() const;
};

struct SceneBoard {
  BoardSpec spec;
  geometry::Rigid3d cam_from_board;
};

// A laser spot on a surface, in the camera frame.
struct SceneDot {
  Eigen::Vector3d p_in_cam = Eigen::Vector3d(0, 0, 1000);  // mm, spot centre
  // 1-sigma radius of the Gaussian spot on the surface, mm. 0: use RenderOptions::dot_sigma_px
  // as an isotropic image-space sigma.
  double sigma_mm = 0.0;
  // Normal of the surface the spot lies on (any length, sign irrelevant). Zero: the surface
  // faces the camera. An oblique surface elongates the projected spot.
  Eigen::Vector3d normal_in_cam = Eigen::Vector3d::Zero();
  double peak = -1.0;  // added level at the spot centre; < 0: RenderOptions::dot_peak
};

// A dot in image space: what is drawn. The spot is the Gaussian
// peak * exp(-0.5 d^T cov^-1 d), d = pixel - centre_px, sampled at pixel centres after
// adding the pixel box's variance (1/12 px^2) and the PSF's (RenderOptions::blur_sigma_px^2)
// to cov; symmetric about centre_px, so its intensity-weighted centroid is centre_px.
struct ImageDot {
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov_px2 = Eigen::Matrix2d::Identity();  // px^2, symmetric positive definite
  double peak = 0.7;
};

struct RenderOptions {
  PixelFormat format = PixelFormat::kMono8;
  double ambient = 0.04;      // level where a ray hits no board
  double board_white = 0.80;  // light squares and the margin
  double board_black = 0.06;  // dark squares
  double board_back = 0.50;   // uniform level of a board seen from its unprinted side
  // Noise: std dev = sqrt(noise_sigma^2 + shot_noise^2 * level), level before clipping.
  double noise_sigma = 0.004;  // signal-independent (read) noise
  double shot_noise = 0.01;    // photon noise std dev at level 1.0
  double dot_sigma_px = 1.5;   // default spot sigma (SceneDot::sigma_mm == 0)
  double dot_peak = 0.7;       // default spot peak; above 1 - background it saturates
  std::array<double, 3> dot_bgr = {0.20, 1.0, 0.12};  // spot weight per channel (B, G, R), kBgr8
  // Optics point-spread function: Gaussian sigma in px applied to the rendered scene (a
  // streaming separable blur; dots get the same variance analytically). 0: none, the image
  // is the exact area average (sharp edges bias cornerSubPix by up to ~0.1 px: pixel locking).
  double blur_sigma_px = 0.8;
  int outline_supersampling = 8;  // S for the S x S samples of board-outline pixels
  uint64_t seed = 0;              // noise seed: same inputs and seed give identical bytes
  // Empty if usable, else "RenderOptions.<field> = <value> violates <constraint>".
  std::string Validate() const;
};

// Counts of how pixels were shaded (for tests and benchmarks).
struct RenderStats {
  int64_t flat_pixels = 0;     // one board (or nothing) covers the footprint, no edge
  int64_t edge_pixels = 0;     // analytic coverage of square edges
  int64_t outline_pixels = 0;  // supersampled: a board outline or occlusion edge crosses it
  int dots_drawn = 0;          // dots in front of the camera that touch the image
};

// Projects a scene dot to image space: centre = cam.Project(p_in_cam); cov = J S J^T with J
// the projection Jacobian and S = sigma_mm^2 (I - n n^T) the spot's covariance in its surface.
// Empty if the dot is behind the camera.
std::optional<ImageDot> ProjectDot(const geometry::CameraModel& cam, const SceneDot& dot,
                                   const RenderOptions& opt);

// Renders a new image of cam.width x cam.height in opt.format (CvType).
// Throws std::invalid_argument naming the field if the camera, a board or the options are
// invalid. Dots behind the camera are skipped.
cv::Mat Render(const geometry::CameraModel& cam, const std::vector<SceneBoard>& boards,
               const std::vector<SceneDot>& dots, const RenderOptions& opt,
               RenderStats* stats = nullptr);

// Renders into a caller-provided image (e.g. a cv::Mat header over an Aravis buffer, any row
// step): `out` must already be cam.height x cam.width of type CvType(opt.format); it is not
// reallocated (throws std::invalid_argument otherwise). Allocates only row buffers and the
// dot patches. Dots are drawn in image space whatever lies in front of them: pass only the
// dots the camera can see. (Pass dots as a typed vector: `{}` is ambiguous between the two
// overloads.) The ImageDot overload also throws if a dot's cov_px2 is not positive definite.
void RenderInto(const geometry::CameraModel& cam, const std::vector<SceneBoard>& boards,
                const std::vector<ImageDot>& dots, const RenderOptions& opt, cv::Mat& out,
                RenderStats* stats = nullptr);
void RenderInto(const geometry::CameraModel& cam, const std::vector<SceneBoard>& boards,
                const std::vector<SceneDot>& dots, const RenderOptions& opt, cv::Mat& out,
                RenderStats* stats = nullptr);

// The board's reflectance level at board point (x_mm, y_mm) seen from its printed side
// (board_white or board_black), or empty outside the printed area. For tests and callers that
// need the canonical colouring without rendering.
std::optional<double> BoardLevelAt(const BoardSpec& spec, double x_mm, double y_mm,
                                   const RenderOptions& opt);

}  // namespace msmcal::render

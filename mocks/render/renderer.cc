#include "mocks/render/renderer.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "mocks/render/ray_map.h"

namespace msmcal::render {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// The footprint half-extent used to classify pixels is estimated from the neighbours' board
// coordinates; it is inflated by this factor so that no pixel crossed by an edge is shaded flat.
constexpr double kFootprintSafety = 1.5;

// ---------------------------------------------------------------------------------------------
// Board geometry in grid units (1 = one square).

struct PreparedBoard {
  bool front = true;  // the camera sees the printed side
  // Ray r = (u, v, 1) in {C}: depth t = dn / (n.r), grid coords gx = (ax.r) / (n.r),
  // gy = (ay.r) / (n.r).
  double n0, n1, n2, dn;
  double ax0, ax1, ax2, ay0, ay1, ay2;
  double xmin, xmax, ymin, ymax;  // printed area (squares plus margin), grid units
  int cols, rows;
};

PreparedBoard Prepare(const SceneBoard& board) {
  const Eigen::Matrix3d r = board.cam_from_board.RotationMatrix();
  const Eigen::Vector3d o = board.cam_from_board.translation;
  const Eigen::Vector3d ex = r.col(0), ey = r.col(1), n = r.col(2);
  const double s = board.spec.square_mm;
  PreparedBoard p;
  p.dn = n.dot(o);
  p.front = p.dn > 0;  // n points away from the printed side, so the camera is on the -n side
  p.n0 = n.x();
  p.n1 = n.y();
  p.n2 = n.z();
  const Eigen::Vector3d ax = (p.dn * ex - ex.dot(o) * n) / s;
  const Eigen::Vector3d ay = (p.dn * ey - ey.dot(o) * n) / s;
  p.ax0 = ax.x();
  p.ax1 = ax.y();
  p.ax2 = ax.z();
  p.ay0 = ay.x();
  p.ay1 = ay.y();
  p.ay2 = ay.z();
  const double m = board.spec.margin_squares;
  p.cols = board.spec.cols;
  p.rows = board.spec.rows;
  p.xmin = -1 - m;
  p.xmax = p.cols + m;
  p.ymin = -1 - m;
  p.ymax = p.rows + m;
  return p;
}

// floor() for |v| < 2^31 without a libm call (the x86-64 baseline has no SSE4.1 round).
inline int FloorInt(double v) {
  const int i = static_cast<int>(v);
  return i - (v < i);
}

inline bool InPrinted(const PreparedBoard& b, double gx, double gy) {
  return gx >= b.xmin && gx <= b.xmax && gy >= b.ymin && gy <= b.ymax;
}

// Dark iff inside the squares and the square's minimum-corner indices (i, j) have even sum.
inline bool DarkAt(const PreparedBoard& b, double gx, double gy) {
  if (!(gx >= -1 && gx < b.cols && gy >= -1 && gy < b.rows)) return false;
  return ((FloorInt(gx) + FloorInt(gy)) & 1) == 0;
}

inline double LevelAt(const PreparedBoard& b, double gx, double gy, const RenderOptions& opt) {
  if (!b.front) return opt.board_back;
  return DarkAt(b, gx, gy) ? opt.board_black : opt.board_white;
}

// ---------------------------------------------------------------------------------------------
// Exact area of a convex polygon clipped to an axis-aligned unit cell.

struct Poly {
  double x[12], y[12];
  int n = 0;
};

// Keeps the part of `in` with sign * (coord - value) >= 0, coord = x (axis 0) or y (axis 1).
void ClipHalfPlane(const Poly& in, int axis, double value, double sign, Poly* out) {
  out->n = 0;
  for (int k = 0; k < in.n; ++k) {
    const int l = (k + 1) % in.n;
    const double ck = sign * ((axis == 0 ? in.x[k] : in.y[k]) - value);
    const double cl = sign * ((axis == 0 ? in.x[l] : in.y[l]) - value);
    if (ck >= 0) {
      out->x[out->n] = in.x[k];
      out->y[out->n] = in.y[k];
      ++out->n;
    }
    if ((ck >= 0) != (cl >= 0)) {
      const double f = ck / (ck - cl);
      out->x[out->n] = in.x[k] + f * (in.x[l] - in.x[k]);
      out->y[out->n] = in.y[k] + f * (in.y[l] - in.y[k]);
      ++out->n;
    }
  }
}

double PolyArea(const Poly& p) {
  double a = 0;
  for (int k = 0; k < p.n; ++k) {
    const int l = (k + 1) % p.n;
    a += p.x[k] * p.y[l] - p.x[l] * p.y[k];
  }
  return 0.5 * std::abs(a);
}

double AreaInCell(const Poly& quad, int i, int j) {
  Poly a, b;
  ClipHalfPlane(quad, 0, i, +1, &a);
  if (a.n == 0) return 0;
  ClipHalfPlane(a, 0, i + 1, -1, &b);
  if (b.n == 0) return 0;
  ClipHalfPlane(b, 1, j, +1, &a);
  if (a.n == 0) return 0;
  ClipHalfPlane(a, 1, j + 1, -1, &b);
  return b.n == 0 ? 0 : PolyArea(b);
}

// Dark fraction of the parallelogram centre (cx, cy) +- a +- b (grid units) on a front board.
double DarkFraction(const PreparedBoard& board, double cx, double cy, const Eigen::Vector2d& a,
                    const Eigen::Vector2d& b) {
  Poly q;
  q.n = 4;
  q.x[0] = cx - a.x() - b.x();
  q.y[0] = cy - a.y() - b.y();
  q.x[1] = cx + a.x() - b.x();
  q.y[1] = cy + a.y() - b.y();
  q.x[2] = cx + a.x() + b.x();
  q.y[2] = cy + a.y() + b.y();
  q.x[3] = cx - a.x() + b.x();
  q.y[3] = cy - a.y() + b.y();
  const double total = 4 * std::abs(a.x() * b.y() - a.y() * b.x());
  const double minx = *std::min_element(q.x, q.x + 4), maxx = *std::max_element(q.x, q.x + 4);
  const double miny = *std::min_element(q.y, q.y + 4), maxy = *std::max_element(q.y, q.y + 4);
  if (!(total > 1e-12) || !(maxx - minx < 8) || !(maxy - miny < 8)) {
    // Degenerate or grazing footprint covering many squares: point-sample it instead.
    constexpr int kS = 16;
    int dark = 0;
    for (int sy = 0; sy < kS; ++sy)
      for (int sx = 0; sx < kS; ++sx) {
        const double fx = 2 * ((sx + 0.5) / kS) - 1, fy = 2 * ((sy + 0.5) / kS) - 1;
        dark += DarkAt(board, cx + fx * a.x() + fy * b.x(), cy + fx * a.y() + fy * b.y());
      }
    return dark / double(kS * kS);
  }
  // Dark cells exist only for i in [-1, cols-1], j in [-1, rows-1]; clamp before converting.
  const auto cell = [](double v, int lo, int hi) {
    return static_cast<int>(std::floor(std::clamp(v, lo - 1.0, hi + 1.0)));
  };
  const int i0 = std::max(cell(minx, -1, board.cols - 1), -1);
  const int i1 = std::min(cell(maxx, -1, board.cols - 1), board.cols - 1);
  const int j0 = std::max(cell(miny, -1, board.rows - 1), -1);
  const int j1 = std::min(cell(maxy, -1, board.rows - 1), board.rows - 1);
  double area = 0;  // empty loops if the footprint misses the squares (margin)
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i)
      if (((i + j) & 1) == 0) area += AreaInCell(q, i, j);
  return std::clamp(area / total, 0.0, 1.0);
}

// ---------------------------------------------------------------------------------------------
// Noise: xoshiro256** and a table of standard normal quantiles (4 samples per 64-bit draw).

double InverseNormalCdf(double p) {
  // Acklam's rational approximation, refined by one Halley step on erfc.
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  constexpr double kLow = 0.02425;
  double x;
  if (p < kLow) {
    const double q = std::sqrt(-2 * std::log(p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  } else if (p <= 1 - kLow) {
    const double q = p - 0.5, r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  } else {
    const double q = std::sqrt(-2 * std::log(1 - p));
    x = -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  const double e = 0.5 * std::erfc(-x / std::sqrt(2.0)) - p;
  const double u = e * std::sqrt(2 * std::numbers::pi) * std::exp(x * x / 2);
  return x - u / (1 + x * u / 2);
}

const std::vector<float>& NormalTable() {
  static const std::vector<float> table = [] {
    std::vector<float> t(65536);
    for (int k = 0; k < 32768; ++k) {
      const double z = InverseNormalCdf((k + 0.5) / 65536.0);
      t[k] = static_cast<float>(z);
      t[65535 - k] = static_cast<float>(-z);  // exactly symmetric: zero mean
    }
    return t;
  }();
  return table;
}

class NormalSource {
 public:
  explicit NormalSource(uint64_t seed) : table_(NormalTable().data()) {
    uint64_t z = seed;
    for (auto& s : s_) {  // splitmix64 expansion of the seed
      z += 0x9E3779B97F4A7C15ull;
      uint64_t x = z;
      x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
      x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
      s = x ^ (x >> 31);
    }
  }
  // n standard normal samples; each 64-bit draw gives four 16-bit table indices.
  void Fill(float* z, int n) {
    int k = 0;
    for (; k + 4 <= n; k += 4) {
      const uint64_t b = NextU64();
      z[k] = table_[b & 0xFFFF];
      z[k + 1] = table_[(b >> 16) & 0xFFFF];
      z[k + 2] = table_[(b >> 32) & 0xFFFF];
      z[k + 3] = table_[b >> 48];
    }
    if (k < n) {
      uint64_t b = NextU64();
      for (; k < n; ++k, b >>= 16) z[k] = table_[b & 0xFFFF];
    }
  }

 private:
  static uint64_t Rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  uint64_t NextU64() {
    const uint64_t result = Rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = Rotl(s_[3], 45);
    return result;
  }
  const float* table_;
  uint64_t s_[4];
};

// ---------------------------------------------------------------------------------------------
// Dots.

struct DotPatch {
  int x0 = 0, y0 = 0, w = 0, h = 0;
  std::vector<float> v;  // h rows of w values (peak-scaled Gaussian)
};

std::optional<DotPatch> MakePatch(const ImageDot& dot, double max_weight, double blur_sigma_px,
                                  int width, int height, size_t index) {
  // The pixel box (1/12 px^2) and the optics PSF add their variances to the spot's.
  const Eigen::Matrix2d c =
      0.5 * (dot.cov_px2 + dot.cov_px2.transpose()) +
      (1.0 / 12.0 + blur_sigma_px * blur_sigma_px) * Eigen::Matrix2d::Identity();
  const double det = c.determinant();
  if (!dot.centre_px.allFinite() || !std::isfinite(dot.peak) || !(c(0, 0) > 0) || !(det > 0)) {
    std::ostringstream s;
    s << "ImageDot[" << index << "]: centre_px must be finite, peak finite and cov_px2 positive "
      << "definite, got centre (" << dot.centre_px.transpose() << "), peak " << dot.peak
      << ", cov [" << dot.cov_px2(0, 0) << ", " << dot.cov_px2(0, 1) << "; " << dot.cov_px2(1, 0)
      << ", " << dot.cov_px2(1, 1) << "]";
    throw std::invalid_argument(s.str());
  }
  const double peak = dot.peak * max_weight;
  if (!(peak > 0)) return std::nullopt;
  const double tr = c.trace();
  const double lam_max = 0.5 * tr + std::sqrt(std::max(0.25 * tr * tr - det, 0.0));
  // Drop the tail below a quarter of a Mono16 count.
  const double cutoff = 0.25 / 65535.0;
  const double k = std::max(3.0, std::sqrt(2 * std::log(std::max(peak / cutoff, 1.0))));
  const double r = std::min(k * std::sqrt(lam_max), 1000.0);
  const double cx = dot.centre_px.x(), cy = dot.centre_px.y();
  if (!(std::abs(cx) < 1e7 && std::abs(cy) < 1e7)) return std::nullopt;  // far off the image
  const int x0 = std::max(static_cast<int>(std::floor(cx - r)), 0);
  const int x1 = std::min(static_cast<int>(std::ceil(cx + r)), width - 1);
  const int y0 = std::max(static_cast<int>(std::floor(cy - r)), 0);
  const int y1 = std::min(static_cast<int>(std::ceil(cy + r)), height - 1);
  if (x1 < x0 || y1 < y0) return std::nullopt;
  DotPatch p;
  p.x0 = x0;
  p.y0 = y0;
  p.w = x1 - x0 + 1;
  p.h = y1 - y0 + 1;
  p.v.resize(static_cast<size_t>(p.w) * p.h);
  const Eigen::Matrix2d ci = c.inverse();
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const double dx = x - cx, dy = y - cy;
      const double q = ci(0, 0) * dx * dx + 2 * ci(0, 1) * dx * dy + ci(1, 1) * dy * dy;
      p.v[static_cast<size_t>(y - y0) * p.w + (x - x0)] =
          static_cast<float>(dot.peak * std::exp(-0.5 * q));
    }
  return p;
}

template <typename T>
std::string Violation(const char* field, T value, const char* constraint) {
  std::ostringstream s;
  s << "RenderOptions." << field << " = " << value << " violates " << constraint;
  return s.str();
}

// Final stage of one row: level = grey + dot * weight[c], plus noise of std dev
// sqrt(read2 + shot2 * level) times the standard normal z, clipped to [0, 1], quantised.
template <int kCh, bool kNoisy, typename T>
void EmitRow(const float* grey, const float* dot, const float* weights, const float* z, float read2,
             float shot2, float maxval, float* level, T* out, int w) {
  for (int x = 0; x < w; ++x)
    for (int c = 0; c < kCh; ++c) level[x * kCh + c] = grey[x] + dot[x] * weights[c];
  const int n = w * kCh;
  for (int k = 0; k < n; ++k) {  // contiguous and branch-free: vectorised at -O3
    float v = level[k];
    if constexpr (kNoisy) v += std::sqrt(read2 + shot2 * std::max(v, 0.0f)) * z[k];
    v = std::min(std::max(v, 0.0f), 1.0f);
    out[k] = static_cast<T>(static_cast<int>(v * maxval + 0.5f));
  }
}

// Board coordinates of one pixel row, in float: they only classify pixels (footprints are
// >= 1e-3 grid units, float error ~1e-6); edge pixels recompute their geometry in double.
struct RowBuf {
  std::vector<float> gx, gy, t;  // t = depth (z in {C}, mm); +inf where the ray misses
  void Resize(int w) {
    gx.resize(w);
    gy.resize(w);
    t.resize(w);
  }
};

constexpr float kInfF = std::numeric_limits<float>::infinity();

void ComputeRow(const PreparedBoard& b, const float* uv, int w, RowBuf* out) {
  float* gx = out->gx.data();
  float* gy = out->gy.data();
  float* t = out->t.data();
  const float n0 = b.n0, n1 = b.n1, n2 = b.n2, dn = b.dn;
  const float ax0 = b.ax0, ax1 = b.ax1, ax2 = b.ax2, ay0 = b.ay0, ay1 = b.ay1, ay2 = b.ay2;
  for (int x = 0; x < w; ++x) {
    const float u = uv[2 * x], v = uv[2 * x + 1];
    const float inv = 1.0f / (n0 * u + n1 * v + n2);
    const float depth = dn * inv;
    gx[x] = (ax0 * u + ax1 * v + ax2) * inv;
    gy[x] = (ay0 * u + ay1 * v + ay2) * inv;
    t[x] = (depth > 0 && depth < kInfF) ? depth : kInfF;
  }
}

// Per pixel of a row on one board: the half-extents (hx, hy) of the pixel footprint along the
// board's grid axes, estimated from the left and upper neighbours (x = 0: right neighbour;
// row 0: row 1) and inflated by kFootprintSafety, and whether the footprint lies inside the
// printed area (2), touches its outline (1) or misses the board (0). Branch-free, written as a
// macro body because GCC 12 vectorises it only in this form.
void ClassifyRow(const PreparedBoard& b, const RowBuf& cur, const RowBuf& prev, int w,
                 float* __restrict hx, float* __restrict hy, int32_t* __restrict code) {
  const float* __restrict gx = cur.gx.data();
  const float* __restrict gy = cur.gy.data();
  const float* __restrict pgx = prev.gx.data();
  const float* __restrict pgy = prev.gy.data();
  const float* __restrict t = cur.t.data();
  const float k = 0.5f * static_cast<float>(kFootprintSafety);
  const float xmin = b.xmin, xmax = b.xmax, ymin = b.ymin, ymax = b.ymax;
#define MSMCAL_RENDER_CLASSIFY(x, xl)                                             \
  {                                                                               \
    const float ax = gx[x], ay = gy[x];                                           \
    const float ex = k * (std::abs(ax - gx[xl]) + std::abs(ax - pgx[x])) + 1e-6f; \
    const float ey = k * (std::abs(ay - gy[xl]) + std::abs(ay - pgy[x])) + 1e-6f; \
    hx[x] = ex;                                                                   \
    hy[x] = ey;                                                                   \
    const int32_t valid = t[x] < kInfF ? 1 : 0;                                   \
    const int32_t in = (ax - ex >= xmin ? 1 : 0) & (ax + ex <= xmax ? 1 : 0) &    \
                       (ay - ey >= ymin ? 1 : 0) & (ay + ey <= ymax ? 1 : 0);     \
    const int32_t touch = (ax + ex >= xmin ? 1 : 0) & (ax - ex <= xmax ? 1 : 0) & \
                          (ay + ey >= ymin ? 1 : 0) & (ay - ey <= ymax ? 1 : 0);  \
    code[x] = (valid & touch) + (valid & in);                                     \
  }
  MSMCAL_RENDER_CLASSIFY(0, 1)
  for (int x = 1; x < w; ++x) MSMCAL_RENDER_CLASSIFY(x, x - 1)
#undef MSMCAL_RENDER_CLASSIFY
}

}  // namespace

int CvType(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
      return CV_8UC1;
    case PixelFormat::kMono16:
      return CV_16UC1;
    case PixelFormat::kBgr8:
      return CV_8UC3;
  }
  return CV_8UC1;
}

const char* ToString(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
      return "Mono8";
    case PixelFormat::kMono16:
      return "Mono16";
    case PixelFormat::kBgr8:
      return "BGR8";
  }
  return "?";
}

std::string BoardSpec::Validate() const {
  std::ostringstream s;
  if (cols < 1)
    s << "BoardSpec.cols = " << cols << " violates cols >= 1";
  else if (rows < 1)
    s << "BoardSpec.rows = " << rows << " violates rows >= 1";
  else if (!(square_mm > 0) || !std::isfinite(square_mm))
    s << "BoardSpec.square_mm = " << square_mm << " violates 0 < square_mm < inf";
  else if (!(margin_squares >= 0 && margin_squares <= 1000))
    s << "BoardSpec.margin_squares = " << margin_squares << " violates 0 <= margin_squares <= 1000";
  else if (cols > 100000 || rows > 100000)
    s << "BoardSpec.cols x rows = " << cols << " x " << rows << " violates cols, rows <= 100000";
  return s.str();
}

std::string RenderOptions::Validate() const {
  const auto level_ok = [](double v) { return v >= 0 && v <= 1; };
  if (format != PixelFormat::kMono8 && format != PixelFormat::kMono16 &&
      format != PixelFormat::kBgr8)
    return Violation("format", static_cast<int>(format), "format in {kMono8, kMono16, kBgr8}");
  if (!level_ok(ambient)) return Violation("ambient", ambient, "0 <= ambient <= 1");
  if (!level_ok(board_white)) return Violation("board_white", board_white, "0 <= board_white <= 1");
  if (!level_ok(board_black)) return Violation("board_black", board_black, "0 <= board_black <= 1");
  if (!level_ok(board_back)) return Violation("board_back", board_back, "0 <= board_back <= 1");
  if (!(noise_sigma >= 0) || !std::isfinite(noise_sigma))
    return Violation("noise_sigma", noise_sigma, "0 <= noise_sigma < inf");
  if (!(shot_noise >= 0) || !std::isfinite(shot_noise))
    return Violation("shot_noise", shot_noise, "0 <= shot_noise < inf");
  if (!(dot_sigma_px > 0 && dot_sigma_px <= 100))
    return Violation("dot_sigma_px", dot_sigma_px, "0 < dot_sigma_px <= 100");
  if (!(dot_peak >= 0) || !std::isfinite(dot_peak))
    return Violation("dot_peak", dot_peak, "0 <= dot_peak < inf");
  for (int c = 0; c < 3; ++c)
    if (!(dot_bgr[c] >= 0) || !std::isfinite(dot_bgr[c]))
      return Violation(c == 0   ? "dot_bgr[0]"
                       : c == 1 ? "dot_bgr[1]"
                                : "dot_bgr[2]",
                       dot_bgr[c], "0 <= weight < inf");
  if (!(blur_sigma_px >= 0 && blur_sigma_px <= 5))
    return Violation("blur_sigma_px", blur_sigma_px, "0 <= blur_sigma_px <= 5");
  if (outline_supersampling < 1 || outline_supersampling > 32)
    return Violation("outline_supersampling", outline_supersampling,
                     "1 <= outline_supersampling <= 32");
  return {};
}

std::optional<ImageDot> ProjectDot(const geometry::CameraModel& cam, const SceneDot& dot,
                                   const RenderOptions& opt) {
  if (!(dot.p_in_cam.z() > 0) || !dot.p_in_cam.allFinite()) return std::nullopt;
  const auto centre = cam.Project(dot.p_in_cam);
  if (!centre) return std::nullopt;
  ImageDot out;
  out.centre_px = *centre;
  out.peak = dot.peak < 0 ? opt.dot_peak : dot.peak;
  if (!(dot.sigma_mm > 0)) {
    out.cov_px2 = opt.dot_sigma_px * opt.dot_sigma_px * Eigen::Matrix2d::Identity();
    return out;
  }
  const double nn = dot.normal_in_cam.norm();
  const Eigen::Vector3d n =
      nn > 0 ? Eigen::Vector3d(dot.normal_in_cam / nn) : Eigen::Vector3d(dot.p_in_cam.normalized());
  const Eigen::Matrix3d s =
      dot.sigma_mm * dot.sigma_mm * (Eigen::Matrix3d::Identity() - n * n.transpose());
  const Eigen::Matrix<double, 2, 3> j = cam.ProjectJacobian(dot.p_in_cam);
  out.cov_px2 = j * s * j.transpose();
  out.cov_px2 = 0.5 * (out.cov_px2 + out.cov_px2.transpose()).eval();
  out.cov_px2 += 1e-4 * Eigen::Matrix2d::Identity();  // an edge-on surface stays drawable
  return out;
}

std::optional<double> BoardLevelAt(const BoardSpec& spec, double x_mm, double y_mm,
                                   const RenderOptions& opt) {
  SceneBoard sb;
  sb.spec = spec;
  sb.cam_from_board = geometry::Rigid3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 1));
  const PreparedBoard b = Prepare(sb);
  const double gx = x_mm / spec.square_mm, gy = y_mm / spec.square_mm;
  if (!InPrinted(b, gx, gy)) return std::nullopt;
  return LevelAt(b, gx, gy, opt);
}

void RenderInto(const geometry::CameraModel& cam, const std::vector<SceneBoard>& boards,
                const std::vector<ImageDot>& dots, const RenderOptions& opt, cv::Mat& out,
                RenderStats* stats) {
  if (const std::string e = cam.Validate(); !e.empty())
    throw std::invalid_argument("Render: camera: " + e);
  if (const std::string e = opt.Validate(); !e.empty()) throw std::invalid_argument("Render: " + e);
  for (size_t i = 0; i < boards.size(); ++i) {
    if (const std::string e = boards[i].spec.Validate(); !e.empty())
      throw std::invalid_argument("Render: boards[" + std::to_string(i) + "]: " + e);
    if (!boards[i].cam_from_board.translation.allFinite() ||
        !boards[i].cam_from_board.rotation.coeffs().allFinite())
      throw std::invalid_argument("Render: boards[" + std::to_string(i) +
                                  "].cam_from_board must be finite");
  }
  const int w = cam.width, h = cam.height;
  if (out.rows != h || out.cols != w || out.type() != CvType(opt.format)) {
    std::ostringstream s;
    s << "RenderInto: out must be " << w << "x" << h << " of type " << ToString(opt.format)
      << ", got " << out.cols << "x" << out.rows << " of OpenCV type " << out.type();
    throw std::invalid_argument(s.str());
  }
  const std::shared_ptr<const RayMap> rays = CachedRayMap(cam);

  std::vector<PreparedBoard> prepared;
  for (const SceneBoard& b : boards) {
    const PreparedBoard p = Prepare(b);
    if (p.dn != 0) prepared.push_back(p);  // the camera in the board's plane sees nothing
  }
  const int nb = static_cast<int>(prepared.size());

  const bool bgr = opt.format == PixelFormat::kBgr8;
  const int nch = bgr ? 3 : 1;
  const double weights[3] = {bgr ? opt.dot_bgr[0] : 1.0, bgr ? opt.dot_bgr[1] : 0.0,
                             bgr ? opt.dot_bgr[2] : 0.0};
  const double max_weight = bgr ? std::max({weights[0], weights[1], weights[2]}) : 1.0;
  std::vector<DotPatch> patches;
  for (size_t i = 0; i < dots.size(); ++i)
    if (auto p = MakePatch(dots[i], max_weight, opt.blur_sigma_px, w, h, i))
      patches.push_back(std::move(*p));

  RenderStats st;
  st.dots_drawn = static_cast<int>(patches.size());
  std::vector<RowBuf> cur(nb), prev(nb);
  std::vector<std::vector<float>> hx(nb, std::vector<float>(w)), hy(nb, std::vector<float>(w));
  std::vector<std::vector<int32_t>> code(nb, std::vector<int32_t>(w));
  for (int b = 0; b < nb; ++b) {
    cur[b].Resize(w);
    prev[b].Resize(w);
  }
  std::vector<float> grey(w), dotrow(w, 0.0f);
  const int s_n = opt.outline_supersampling;

  const auto supersample = [&](int x, int y) {
    const Eigen::Vector2d uv0 = rays->At(x, y);
    const Eigen::Matrix2d j = rays->Jacobian(x, y);
    double sum = 0;
    for (int sy = 0; sy < s_n; ++sy)
      for (int sx = 0; sx < s_n; ++sx) {
        const Eigen::Vector2d d((sx + 0.5) / s_n - 0.5, (sy + 0.5) / s_n - 0.5);
        const Eigen::Vector2d uv = uv0 + j * d;
        double best_t = kInf, level = opt.ambient;
        for (const PreparedBoard& b : prepared) {
          const double inv = 1.0 / (b.n0 * uv.x() + b.n1 * uv.y() + b.n2);
          const double t = b.dn * inv;
          if (!(t > 0 && t < best_t)) continue;
          const double gx = (b.ax0 * uv.x() + b.ax1 * uv.y() + b.ax2) * inv;
          const double gy = (b.ay0 * uv.x() + b.ay1 * uv.y() + b.ay2) * inv;
          if (!InPrinted(b, gx, gy)) continue;
          best_t = t;
          level = LevelAt(b, gx, gy, opt);
        }
        sum += level;
      }
    return sum / (s_n * s_n);
  };

  const auto analytic = [&](const PreparedBoard& b, int x, int y) {
    const Eigen::Vector2d uv = rays->At(x, y);
    const Eigen::Matrix2d juv = rays->Jacobian(x, y);
    const double nr = b.n0 * uv.x() + b.n1 * uv.y() + b.n2;
    const double gx = (b.ax0 * uv.x() + b.ax1 * uv.y() + b.ax2) / nr;
    const double gy = (b.ay0 * uv.x() + b.ay1 * uv.y() + b.ay2) / nr;
    Eigen::Matrix2d dg_duv;
    dg_duv << (b.ax0 - gx * b.n0) / nr, (b.ax1 - gx * b.n1) / nr, (b.ay0 - gy * b.n0) / nr,
        (b.ay1 - gy * b.n1) / nr;
    const Eigen::Matrix2d g = dg_duv * juv;  // columns: grid displacement per pixel in x, y
    const double frac = DarkFraction(b, gx, gy, 0.5 * g.col(0), 0.5 * g.col(1));
    return opt.board_white + (opt.board_black - opt.board_white) * frac;
  };

  // Optics PSF: Gaussian kernel sampled at integer offsets, normalised, radius ceil(3 sigma).
  const int blur_radius =
      opt.blur_sigma_px > 0 ? static_cast<int>(std::ceil(3 * opt.blur_sigma_px)) : 0;
  std::vector<float> kernel(2 * blur_radius + 1, 1.0f);
  if (blur_radius > 0) {
    double sum = 0;
    for (int d = -blur_radius; d <= blur_radius; ++d)
      sum += std::exp(-0.5 * d * d / (opt.blur_sigma_px * opt.blur_sigma_px));
    for (int d = -blur_radius; d <= blur_radius; ++d)
      kernel[d + blur_radius] = static_cast<float>(
          std::exp(-0.5 * d * d / (opt.blur_sigma_px * opt.blur_sigma_px)) / sum);
  }

  const bool noisy = opt.noise_sigma > 0 || opt.shot_noise > 0;
  std::vector<float> noise(static_cast<size_t>(w) * nch), levels(static_cast<size_t>(w) * nch);
  NormalSource normal(opt.seed);
  const float read2 = static_cast<float>(opt.noise_sigma * opt.noise_sigma);
  const float shot2 = static_cast<float>(opt.shot_noise * opt.shot_noise);
  const float maxval = opt.format == PixelFormat::kMono16 ? 65535.0f : 255.0f;
  const float fweights[3] = {static_cast<float>(weights[0]), static_cast<float>(weights[1]),
                             static_cast<float>(weights[2])};

  // Shades row y (rows must come in order 0, 1, 2, ...) into grey_out[0..w).
  const auto shade_row = [&](int y, float* grey_out) {
    // Board coordinates of this row and the previous one (row 1 stands in for row -1).
    for (int b = 0; b < nb; ++b) {
      if (y == 0) {
        ComputeRow(prepared[b], rays->Row(0), w, &cur[b]);
        ComputeRow(prepared[b], rays->Row(1), w, &prev[b]);
      } else {
        std::swap(cur[b], prev[b]);
        ComputeRow(prepared[b], rays->Row(y), w, &cur[b]);
      }
    }
    for (int b = 0; b < nb; ++b)
      ClassifyRow(prepared[b], cur[b], prev[b], w, hx[b].data(), hy[b].data(), code[b].data());
    for (int x = 0; x < w; ++x) {
      double best_t = kInf, outline_t = kInf;
      int best = -1;
      for (int b = 0; b < nb; ++b) {
        const int32_t k = code[b][x];
        if (k == 0) continue;
        const double t = cur[b].t[x];  // finite where k != 0
        if (k == 2) {
          if (t < best_t) {
            best_t = t;
            best = b;
          }
        } else {
          outline_t = std::min(outline_t, t);
        }
      }
      double level;
      if (outline_t < best_t) {
        level = supersample(x, y);
        ++st.outline_pixels;
      } else if (best < 0) {
        level = opt.ambient;
        ++st.flat_pixels;
      } else {
        const PreparedBoard& pb = prepared[best];
        const double bgx = cur[best].gx[x], bgy = cur[best].gy[x];
        const double bhx = hx[best][x], bhy = hy[best][x];
        if (!pb.front) {
          level = opt.board_back;
          ++st.flat_pixels;
        } else {
          const double rx = FloorInt(bgx + 0.5), ry = FloorInt(bgy + 0.5);
          const bool near_v = std::abs(bgx - rx) <= bhx && rx >= -1 && rx <= pb.cols &&
                              bgy >= -1 - bhy && bgy <= pb.rows + bhy;
          const bool near_h = std::abs(bgy - ry) <= bhy && ry >= -1 && ry <= pb.rows &&
                              bgx >= -1 - bhx && bgx <= pb.cols + bhx;
          if (near_v || near_h) {
            level = analytic(pb, x, y);
            ++st.edge_pixels;
          } else {
            level = DarkAt(pb, bgx, bgy) ? opt.board_black : opt.board_white;
            ++st.flat_pixels;
          }
        }
      }
      grey_out[x] = static_cast<float>(level);
    }
  };

  // Adds the dots to the (blurred) grey row y, applies noise, clips, quantises, writes.
  const auto emit_row = [&](int y, const float* grey) {
    // Dots of this row.
    int dmin = w, dmax = -1;
    for (const DotPatch& p : patches) {
      if (y < p.y0 || y >= p.y0 + p.h) continue;
      const float* src = p.v.data() + static_cast<size_t>(y - p.y0) * p.w;
      for (int k = 0; k < p.w; ++k) dotrow[p.x0 + k] += src[k];
      dmin = std::min(dmin, p.x0);
      dmax = std::max(dmax, p.x0 + p.w - 1);
    }

    // Noise, clipping, quantisation.
    if (noisy) normal.Fill(noise.data(), w * nch);
    const float* z = noise.data();
    float* lev = levels.data();
    const float* dr = dotrow.data();
    if (opt.format == PixelFormat::kMono16) {
      uint16_t* o = out.ptr<uint16_t>(y);
      noisy ? EmitRow<1, true>(grey, dr, fweights, z, read2, shot2, maxval, lev, o, w)
            : EmitRow<1, false>(grey, dr, fweights, z, read2, shot2, maxval, lev, o, w);
    } else if (nch == 3) {
      uint8_t* o = out.ptr<uint8_t>(y);
      noisy ? EmitRow<3, true>(grey, dr, fweights, z, read2, shot2, maxval, lev, o, w)
            : EmitRow<3, false>(grey, dr, fweights, z, read2, shot2, maxval, lev, o, w);
    } else {
      uint8_t* o = out.ptr<uint8_t>(y);
      noisy ? EmitRow<1, true>(grey, dr, fweights, z, read2, shot2, maxval, lev, o, w)
            : EmitRow<1, false>(grey, dr, fweights, z, read2, shot2, maxval, lev, o, w);
    }
    if (dmax >= dmin) std::fill(dotrow.begin() + dmin, dotrow.begin() + dmax + 1, 0.0f);
  };

  if (blur_radius == 0) {
    for (int y = 0; y < h; ++y) {
      shade_row(y, grey.data());
      emit_row(y, grey.data());
    }
  } else {
    // Streaming separable Gaussian (the optics' PSF) over a ring of 2R+1 shaded rows; image
    // borders replicate.
    const int taps = 2 * blur_radius + 1;
    std::vector<float> ring(static_cast<size_t>(taps) * w);
    std::vector<float> vert(w + 2 * blur_radius);
    for (int y_in = 0; y_in < h + blur_radius; ++y_in) {
      if (y_in < h) shade_row(y_in, ring.data() + static_cast<size_t>(y_in % taps) * w);
      const int y = y_in - blur_radius;
      if (y < 0) continue;
      float* v = vert.data() + blur_radius;
      std::fill(v, v + w, 0.0f);
      for (int d = -blur_radius; d <= blur_radius; ++d) {
        const int yy = std::clamp(y + d, 0, h - 1);
        const float* src = ring.data() + static_cast<size_t>(yy % taps) * w;
        const float k = kernel[d + blur_radius];
        for (int x = 0; x < w; ++x) v[x] += k * src[x];
      }
      for (int d = 1; d <= blur_radius; ++d) {
        v[-d] = v[0];
        v[w - 1 + d] = v[w - 1];
      }
      for (int x = 0; x < w; ++x) {
        float acc = 0;
        for (int d = -blur_radius; d <= blur_radius; ++d) acc += kernel[d + blur_radius] * v[x + d];
        grey[x] = acc;
      }
      emit_row(y, grey.data());
    }
  }
  if (stats) *stats = st;
}

void RenderInto(const geometry::CameraModel& cam, const std::vector<SceneBoard>& boards,
                const std::vector<SceneDot>& dots, const RenderOptions& opt, cv::Mat& out,
                RenderStats* stats) {
  if (const std::string e = opt.Validate(); !e.empty()) throw std::invalid_argument("Render: " + e);
  std::vector<ImageDot> image_dots;
  image_dots.reserve(dots.size());
  for (const SceneDot& d : dots)
    if (auto id = ProjectDot(cam, d, opt)) image_dots.push_back(*id);
  RenderInto(cam, boards, image_dots, opt, out, stats);
}

cv::Mat Render(const geometry::CameraModel& cam, const std::vector<SceneBoard>& boards,
               const std::vector<SceneDot>& dots, const RenderOptions& opt, RenderStats* stats) {
  if (const std::string e = cam.Validate(); !e.empty())
    throw std::invalid_argument("Render: camera: " + e);
  if (const std::string e = opt.Validate(); !e.empty()) throw std::invalid_argument("Render: " + e);
  cv::Mat out(cam.height, cam.width, CvType(opt.format));
  RenderInto(cam, boards, dots, opt, out, stats);
  return out;
}

}  // namespace msmcal::render

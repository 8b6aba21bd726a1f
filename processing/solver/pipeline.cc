#include "processing/solver/pipeline.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <map>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

#include "processing/geometry/mirror_frame.h"
#include "processing/solver/home_frame.h"

namespace msmcal::solver {
namespace {

using dataset::Step2Kind;
using geometry::Line;
using geometry::Plane;
using geometry::Rigid3d;

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr double kDegToRad = M_PI / 180.0;
// A step 1 dot farther than this from its beam's line (fitted to all its labelled dots) marks
// its frame's dot-to-beam labels as wrong (a non-laser blob counted as a dot, or a swapped
// permutation); the frame is dropped from the beam fit (docs/solver.md, "Step 1 label check").
// Correctly labelled sliding-board dots sit ~0.05 mm from the line in simulation.
constexpr double kMaxBeamLineResidualMm = 1.0;

std::string SizeText(const dataset::BoardSpec& b) {
  return std::to_string(b.cols) + "x" + std::to_string(b.rows);
}

std::vector<Eigen::Vector3d> BoardPoints(const dataset::BoardSpec& b) {
  std::vector<Eigen::Vector3d> p;
  for (int r = 0; r < b.rows; ++r)
    for (int c = 0; c < b.cols; ++c) p.emplace_back(c * b.square_mm, r * b.square_mm, 0.0);
  return p;
}

// Best assignment of `n` items to `n` slots minimising sum cost(i, slot): brute force up to 7,
// greedy above.
std::vector<int> BestPermutation(int n, const std::function<double(int, int)>& cost) {
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  if (n > 7) {
    std::vector<int> out(n, -1);
    std::vector<bool> used(n, false);
    for (int i = 0; i < n; ++i) {
      int best = -1;
      for (int s = 0; s < n; ++s)
        if (!used[s] && (best < 0 || cost(i, s) < cost(i, best))) best = s;
      out[i] = best;
      used[best] = true;
    }
    return out;
  }
  std::vector<int> best = perm;
  double best_cost = 1e300;
  do {
    double c = 0;
    for (int i = 0; i < n && c < best_cost; ++i) c += cost(i, perm[i]);
    if (c < best_cost) {
      best_cost = c;
      best = perm;
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  return best;
}

Eigen::VectorXd Features(double t, bool slow_on, double wf, double ws, bool harmonics) {
  Eigen::VectorXd f(harmonics ? 9 : 5);
  const double m = slow_on ? 1.0 : 0.0;
  f(0) = 1;
  f(1) = std::sin(wf * t);
  f(2) = std::cos(wf * t);
  f(3) = m * std::sin(ws * t);
  f(4) = m * std::cos(ws * t);
  if (harmonics) {
    f(5) = std::sin(2 * wf * t);
    f(6) = std::cos(2 * wf * t);
    f(7) = m * std::sin(2 * ws * t);
    f(8) = m * std::cos(2 * ws * t);
  }
  return f;
}

// Board (c, r) -> image homography of a detection, in squares (identity if it cannot be fitted).
cv::Matx33d BoardHomographyOrIdentity(const vision::CheckerboardDetection& board,
                                      vision::BoardSize size) {
  const cv::Mat h = vision::BoardHomography(board, size);
  return h.empty() ? cv::Matx33d::eye() : cv::Matx33d(h);
}

// Elongation (ratio of principal std devs) of a blob's shape mapped into the board's plane: a
// laser spot is round there (or elongated by its incidence), whatever the plane's tilt to the
// camera; board structure (top-hat residue of square corners and edges) is not.
double SurfaceElongation(const vision::Dot& d, const cv::Matx33d& h) {
  const cv::Matx33d hi = h.inv();
  const cv::Vec3d u = hi * cv::Vec3d(d.centroid_px.x(), d.centroid_px.y(), 1.0);
  if (std::abs(u[2]) < 1e-12) return 1e9;
  const double bx = u[0] / u[2], by = u[1] / u[2];
  const double w = h(2, 0) * bx + h(2, 1) * by + h(2, 2);
  const double x = (h(0, 0) * bx + h(0, 1) * by + h(0, 2)) / w;
  const double y = (h(1, 0) * bx + h(1, 1) * by + h(1, 2)) / w;
  Eigen::Matrix2d j;
  j << (h(0, 0) - x * h(2, 0)) / w, (h(0, 1) - x * h(2, 1)) / w, (h(1, 0) - y * h(2, 0)) / w,
      (h(1, 1) - y * h(2, 1)) / w;
  if (std::abs(j.determinant()) < 1e-12) return 1e9;
  const Eigen::Matrix2d ji = j.inverse();
  const Eigen::Matrix2d surf = ji * d.scatter_px2 * ji.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(0.5 * (surf + surf.transpose()));
  return std::sqrt(es.eigenvalues()(1) / std::max(es.eigenvalues()(0), 1e-300));
}

// RMS distance between a board's detected corners and their projection through the PnP pose;
// -1 if none projects.
double ReprojectionRms(const geometry::CameraModel& camera, const Rigid3d& cam_from_board,
                       const std::vector<Eigen::Vector3d>& pts,
                       const std::vector<Eigen::Vector2d>& px) {
  double s2 = 0;
  int n = 0;
  for (size_t i = 0; i < pts.size() && i < px.size(); ++i)
    if (const auto p = camera.Project(cam_from_board * pts[i])) {
      s2 += (*p - px[i]).squaredNorm();
      ++n;
    }
  return n ? std::sqrt(s2 / n) : -1.0;
}

// Why blobs of a frame were not taken as its laser dots (results/detections.csv).
struct RegionRejections {
  int off_plane = 0;          // outside the board's plane (beyond the margin, on the other board)
  int junction = 0;           // at a square corner, elongated: top-hat residue
  int surface_elongated = 0;  // elongated in the board's plane
};

// The frame's dots on its board's plane, and the blobs refused there, into its detection row.
void RecordDots(const std::vector<vision::Dot>& on_plane, const std::vector<vision::Dot>& all,
                const RegionRejections& region, FrameDetection* fd) {
  fd->dots_found = static_cast<int>(on_plane.size());
  fd->off_plane = region.off_plane;
  fd->junction = region.junction;
  fd->surface_elongated = region.surface_elongated;
  for (const auto& d : on_plane) fd->dots_px.push_back(d.px);
  for (const auto& d : all)
    if (std::none_of(on_plane.begin(), on_plane.end(),
                     [&](const vision::Dot& k) { return k.px == d.px; }))
      fd->refused_px.push_back(d.px);
}

// Laser dots land on the board's plane: the blobs inside the board's squares area grown by
// `margin_squares` (the plate or screen around the printed pattern), not inside `exclude` (the
// other board's outline, grown by half a square), round in the board's plane.
std::vector<vision::Dot> DotsOnBoard(const std::vector<vision::Dot>& dots,
                                     const vision::CheckerboardDetection& board,
                                     vision::BoardSize size, double margin_squares,
                                     const PipelineOptions& o,
                                     const std::vector<Eigen::Vector2d>& exclude,
                                     RegionRejections* rej) {
  const auto outline = vision::SquaresOutline(board, size, margin_squares);
  // The host board's own printed area wins over the other board's outline (the sliding plate
  // may hide part of the world board in the image).
  const auto own_area = vision::SquaresOutline(board, size, 0.5);
  const cv::Matx33d h = BoardHomographyOrIdentity(board, size);
  const double junction_px = o.junction_exclusion_squares * board.square_px;
  std::vector<vision::Dot> out;
  for (const auto& d : dots) {
    if (!vision::InsideOutline(outline, d.px) ||
        (!exclude.empty() && vision::InsideOutline(exclude, d.px) &&
         !vision::InsideOutline(own_area, d.px))) {
      ++rej->off_plane;
      continue;
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(d.scatter_px2);
    const double image_elongation =
        std::sqrt(es.eigenvalues()(1) / std::max(es.eigenvalues()(0), 1e-12));
    if (image_elongation > o.junction_elongation) {
      bool at_corner = false;
      for (const auto& c : board.corners_px)
        at_corner = at_corner || (c - d.px).norm() < junction_px;
      if (at_corner) {
        ++rej->junction;
        continue;
      }
    }
    if (SurfaceElongation(d, h) > o.max_surface_elongation) {
      ++rej->surface_elongated;
      continue;
    }
    out.push_back(d);
  }
  return out;
}

// The corners of `board` that no laser dot of the frame disturbs (their average over a view
// leaves the others out).
std::vector<char> CornersClearOfDots(const vision::CheckerboardDetection& board,
                                     const std::vector<vision::Dot>& dots) {
  std::vector<cv::Rect> boxes;
  for (const auto& d : dots) boxes.push_back(d.blob_box);
  return vision::CornersClearOfSpots(board, boxes);
}

// Frames of a static board seen by a fixed camera (the world board in every step 1 frame for
// C1 and in every step 2 frame for C2, a sliding pose seen in several frames) repeat the same
// view: their corner errors are mostly the detector's per-corner bias, the same in every frame,
// not independent noise. Each view enters the MLE once, as the mean of its frames' corners, so
// that the pose information is not counted K times (docs/solver.md, "Covariance honesty").
// A corner is averaged over the frames where it is clear of laser dots (`clear[k][i]`); a
// corner that no frame sees clear is left out of the view, and a view left with fewer than 4
// corners is left out whole. `dropped` counts the corners left out.
std::vector<CornerSet> MergeRepeatedViews(const std::vector<CornerSet>& sets,
                                          const std::vector<std::vector<char>>& clear,
                                          int* dropped) {
  std::vector<CornerSet> sum;
  std::vector<std::vector<int>> count;
  for (size_t k = 0; k < sets.size(); ++k) {
    const CornerSet& cs = sets[k];
    size_t v = 0;
    while (v < sum.size() &&
           !(sum[v].view == cs.view && sum[v].pose == cs.pose && sum[v].px.size() == cs.px.size()))
      ++v;
    if (v == sum.size()) {
      sum.push_back(cs);
      for (auto& p : sum.back().px) p.setZero();
      count.emplace_back(cs.px.size(), 0);
    }
    for (size_t i = 0; i < cs.px.size(); ++i) {
      if (!clear[k][i]) continue;
      sum[v].px[i] += cs.px[i];
      ++count[v][i];
    }
  }
  std::vector<CornerSet> out;
  *dropped = 0;
  for (size_t v = 0; v < sum.size(); ++v) {
    CornerSet m{sum[v].view, sum[v].pose, {}, {}};
    for (size_t i = 0; i < sum[v].px.size(); ++i) {
      if (count[v][i] == 0) {
        ++*dropped;
        continue;
      }
      m.points_in_board.push_back(sum[v].points_in_board[i]);
      m.px.push_back(sum[v].px[i] / count[v][i]);
    }
    if (m.px.size() >= 4)
      out.push_back(std::move(m));
    else
      *dropped += static_cast<int>(m.px.size());
  }
  return out;
}

struct Group {
  int frame = 0;                   // index into the step 2 frame list
  std::map<int, int> dot_of_beam;  // beam index -> dot index in the frame
  Plane plane;
  int slot = 0;  // index into the frame's trigger list
};

}  // namespace

std::string PipelineOptions::Validate() const {
  if (std::string e = dots.Validate(); !e.empty()) return "dots." + e;
  if (std::string e = boards.Validate(); !e.empty()) return "boards." + e;
  if (std::string e = mle.Validate(); !e.empty()) return "mle." + e;
  std::ostringstream s;
  if (!(step1_dot_margin_squares >= 0 && step1_dot_margin_squares <= 1000))
    s << "step1_dot_margin_squares = " << step1_dot_margin_squares << " must be in [0, 1000]";
  else if (!(step2_dot_margin_squares >= 0 && step2_dot_margin_squares <= 1000))
    s << "step2_dot_margin_squares = " << step2_dot_margin_squares << " must be in [0, 1000]";
  else if (!(max_surface_elongation >= 1 && max_surface_elongation <= 100))
    s << "max_surface_elongation = " << max_surface_elongation << " must be in [1, 100]";
  else if (!(junction_elongation >= 1))
    s << "junction_elongation = " << junction_elongation << " must be >= 1";
  else if (!(junction_exclusion_squares >= 0 && junction_exclusion_squares <= 1))
    s << "junction_exclusion_squares = " << junction_exclusion_squares << " must be in [0, 1]";
  else if (!(adaptive_min_relative_peak >= 0 && adaptive_min_relative_peak < 1))
    s << "adaptive_min_relative_peak = " << adaptive_min_relative_peak << " must be in [0, 1)";
  else if (max_surplus_dots < 0 || max_surplus_dots > 50)
    s << "max_surplus_dots = " << max_surplus_dots << " must be in [0, 50]";
  else if (!(max_group_residual_px > 0))
    s << "max_group_residual_px = " << max_group_residual_px << " must be > 0";
  else if (!(partial_frame_group_residual_px > 0))
    s << "partial_frame_group_residual_px = " << partial_frame_group_residual_px << " must be > 0";
  else if (ransac_iterations < 1)
    s << "ransac_iterations = " << ransac_iterations << " must be >= 1";
  else if (!(ransac_inlier_deg > 0))
    s << "ransac_inlier_deg = " << ransac_inlier_deg << " must be > 0";
  else if (image_threads < 1)
    s << "image_threads = " << image_threads << " must be >= 1";
  return s.str();
}

Eigen::Vector2d TriggerModel::Predict(double t_s, bool slow_on) const {
  return coef.transpose() *
         Features(t_s, slow_on, 2 * M_PI * fast_hz, 2 * M_PI * slow_hz, harmonics);
}

std::vector<int> AssignTriggers(const std::vector<TriggerFrame>& frames,
                                const std::vector<TriggerGroup>& groups,
                                const std::vector<Eigen::Vector2d>& neutral_angles_deg,
                                double fast_hz, double slow_hz, const PipelineOptions& o,
                                std::string* note, TriggerModel* model) {
  const double wf = 2 * M_PI * fast_hz, ws = 2 * M_PI * slow_hz;
  std::vector<std::vector<int>> of_frame(frames.size());
  for (size_t g = 0; g < groups.size(); ++g)
    of_frame[groups[g].frame].push_back(static_cast<int>(g));
  std::vector<int> slot(groups.size(), 0);
  auto fit = [&](const std::vector<std::pair<int, int>>& labelled, bool harmonics,
                 Eigen::MatrixXd* coef) {
    const int p = harmonics ? 9 : 5;
    const int n = static_cast<int>(labelled.size() + neutral_angles_deg.size());
    Eigen::MatrixXd a(n, p);
    Eigen::MatrixXd y(n, 2);
    int r = 0;
    for (const auto& [g, s] : labelled) {
      const auto& fr = frames[groups[g].frame];
      a.row(r) = Features(fr.t_s[s], fr.slow_on, wf, ws, harmonics).transpose();
      y.row(r++) = groups[g].angles_deg.transpose();
    }
    for (const auto& na : neutral_angles_deg) {
      a.row(r).setZero();
      a(r, 0) = 1;
      y.row(r++) = na.transpose();
    }
    // Small ridge keeps under-determined samples solvable.
    const Eigen::MatrixXd ata = a.transpose() * a + 1e-9 * Eigen::MatrixXd::Identity(p, p);
    *coef = ata.ldlt().solve(a.transpose() * y);
  };
  auto assign = [&](const Eigen::MatrixXd& coef, bool harmonics, std::vector<int>* out) {
    const double thr2 = o.ransac_inlier_deg * o.ransac_inlier_deg;
    double score = 0;
    for (size_t f = 0; f < frames.size(); ++f) {
      const auto& gs = of_frame[f];
      if (gs.empty()) continue;
      const int n = static_cast<int>(frames[f].t_s.size());
      std::vector<Eigen::Vector2d> pred(n);
      for (int s = 0; s < n; ++s)
        pred[s] =
            coef.transpose() * Features(frames[f].t_s[s], frames[f].slow_on, wf, ws, harmonics);
      auto cost = [&](int i, int s) {
        if (i >= static_cast<int>(gs.size())) return 0.0;
        return std::min((groups[gs[i]].angles_deg - pred[s]).squaredNorm(), thr2);
      };
      const std::vector<int> perm = BestPermutation(n, cost);
      for (size_t i = 0; i < gs.size(); ++i) {
        score += cost(static_cast<int>(i), perm[i]);
        if (out) (*out)[gs[i]] = perm[i];
      }
    }
    return score;
  };
  std::vector<int> multi;
  for (size_t f = 0; f < frames.size(); ++f)
    if (!of_frame[f].empty()) multi.push_back(static_cast<int>(f));
  std::mt19937_64 rng(o.seed);
  Eigen::MatrixXd best_coef;
  double best_score = 1e300;
  const int sample = neutral_angles_deg.empty() ? 5 : 4;
  for (int it = 0; it < o.ransac_iterations && !multi.empty(); ++it) {
    std::vector<std::pair<int, int>> labelled;
    for (int k = 0; k < sample; ++k) {
      const int f = multi[std::uniform_int_distribution<int>(0, multi.size() - 1)(rng)];
      const auto& gs = of_frame[f];
      const int g = gs[std::uniform_int_distribution<int>(0, gs.size() - 1)(rng)];
      const int s = std::uniform_int_distribution<int>(0, frames[f].t_s.size() - 1)(rng);
      labelled.emplace_back(g, s);
    }
    Eigen::MatrixXd coef;
    fit(labelled, false, &coef);
    const double score = assign(coef, false, nullptr);
    if (score < best_score) {
      best_score = score;
      best_coef = coef;
    }
  }
  if (multi.empty()) return slot;
  assign(best_coef, false, &slot);
  Eigen::MatrixXd coef = best_coef;
  bool harmonics = false;
  for (int round = 0; round < 4; ++round) {
    std::vector<std::pair<int, int>> labelled;
    for (size_t g = 0; g < groups.size(); ++g) labelled.emplace_back(static_cast<int>(g), slot[g]);
    harmonics = labelled.size() + neutral_angles_deg.size() >= 18;
    fit(labelled, harmonics, &coef);
    assign(coef, harmonics, &slot);
  }
  if (model) *model = TriggerModel{coef, harmonics, fast_hz, slow_hz};
  if (note) {
    double sum2 = 0;
    for (size_t g = 0; g < groups.size(); ++g) {
      const auto& fr = frames[groups[g].frame];
      const Eigen::Vector2d pred =
          coef.transpose() * Features(fr.t_s[slot[g]], fr.slow_on, wf, ws, harmonics);
      sum2 += (groups[g].angles_deg - pred).squaredNorm();
    }
    std::ostringstream s;
    s << "trigger assignment: " << groups.size() << " groups in " << multi.size()
      << " multi-trigger frames, drive-phase model RMS "
      << std::sqrt(sum2 / std::max<size_t>(1, groups.size())) << " deg";
    *note = s.str();
  }
  return slot;
}

namespace {

// What one image shows: the boards asked for (in order) and the laser dots. Measured for all
// images before the solve, `threads` images at a time; each image is measured on one thread
// and stored by its index, so the outcome does not depend on the scheduling.

// Turns OpenCV's own parallel loops off while alive (restores the previous setting): their
// results depend on the number of CPUs and on the load (stripe boundaries and completion
// order), and a solve must give the same digits on every run.
class OpenCvSerial {
 public:
  OpenCvSerial() : previous_(cv::getNumThreads()) { cv::setNumThreads(0); }
  ~OpenCvSerial() { cv::setNumThreads(previous_); }
  OpenCvSerial(const OpenCvSerial&) = delete;
  OpenCvSerial& operator=(const OpenCvSerial&) = delete;

 private:
  int previous_;
};

// Runs fn(0) .. fn(count - 1), `threads` at a time (each index on one thread); rethrows the
// exception of the first failing index, so the error does not depend on the scheduling.
void ForEachImage(size_t count, int threads, const std::function<void(size_t)>& fn) {
  std::vector<std::exception_ptr> errors(count);
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t i = next++; i < count; i = next++) {
      try {
        fn(i);
      } catch (...) {
        errors[i] = std::current_exception();
      }
    }
  };
  const size_t n = std::min<size_t>(static_cast<size_t>(threads), std::max<size_t>(1, count));
  std::vector<std::thread> pool;
  for (size_t t = 1; t < n; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
}

// The dots of a measured image that lie on the plane of the board that carries them (step 1:
// the sliding board, boards[1], never on the world board; step 2: the world board, boards[0]).
std::vector<vision::Dot> DotsOnHostPlane(const std::vector<vision::Dot>& dots,
                                         const ImageMeasurement& m,
                                         const std::vector<vision::BoardSize>& sizes,
                                         const PipelineOptions& o, RegionRejections* rej) {
  if (sizes.size() == 2) {
    return DotsOnBoard(dots, *m.boards[1], sizes[1], o.step1_dot_margin_squares, o,
                       m.boards[0] ? vision::SquaresOutline(*m.boards[0], sizes[0], 0.5)
                                   : std::vector<Eigen::Vector2d>{},
                       rej);
  }
  return DotsOnBoard(dots, *m.boards[0], sizes[0], o.step2_dot_margin_squares, o, {}, rej);
}

// `expected[i]`: the dots image i should show (0: not checked). An image whose first pass finds
// fewer on its board's plane is measured again with settings from its own data
// (AdaptiveDotOptions); the second pass is kept if it finds more.
std::vector<ImageMeasurement> MeasureImages(
    const std::vector<std::string>& files,
    const std::vector<std::vector<vision::BoardSize>>& boards, const ImageLoader& load,
    const PipelineOptions& o, const std::vector<int>& expected) {
  std::vector<ImageMeasurement> out(files.size());
  ForEachImage(files.size(), o.image_threads, [&](size_t i) {
    const cv::Mat img = load(files[i]);
    if (img.empty()) throw SolveError(files[i] + ": cannot read the image");
    out[i] = MeasureFrame(img, boards[i], expected[i], o);
  });
  return out;
}

// Refits every dot over a background measured in the other images of its static group (same
// camera and board placement: all of step 2; step 1 image by sliding pose), where its pixels
// are dot-free (vision/dots.h). The images are read a second time, `threads` at a time; the
// background sums are added in image order, so the result does not depend on the scheduling.
// Dots without a dot-free view of every window pixel keep their first measurement.
void RefineDotsOnBackgrounds(const std::vector<std::vector<size_t>>& groups,
                             const std::vector<std::string>& files, const ImageLoader& load,
                             const vision::DotOptions& dot_options, int threads,
                             std::vector<ImageMeasurement>* measured) {
  struct Window {
    size_t image, dot;
  };
  std::vector<std::vector<Window>> windows(groups.size());
  std::vector<int> group_of(files.size(), -1);
  for (size_t g = 0; g < groups.size(); ++g) {
    if (groups[g].size() < 2) continue;
    for (size_t i : groups[g]) {
      group_of[i] = static_cast<int>(g);
      const auto& m = (*measured)[i];
      // Only images whose board was found take part (their dots are the ones used, and only
      // they are read again below).
      if (m.boards.empty() || !m.boards.back()) continue;
      for (size_t k = 0; k < m.dots.size(); ++k) windows[g].push_back({i, k});
    }
  }
  // Per image: its contribution to its group's windows, and its own dots' signal patches.
  std::vector<std::vector<vision::BackgroundPatch>> contribution(files.size());
  std::vector<std::vector<vision::DotSignalPatch>> own(files.size());
  // A dot's window needs its image's size; a group whose images differ in size is skipped.
  std::vector<cv::Size> sizes(files.size());
  ForEachImage(files.size(), threads, [&](size_t i) {
    if (group_of[i] < 0 || (*measured)[i].boards.empty() || !(*measured)[i].boards.back()) return;
    const cv::Mat img = load(files[i]);
    if (img.empty()) throw SolveError(files[i] + ": cannot read the image");
    sizes[i] = img.size();
    std::vector<cv::Rect> rects;
    for (const Window& w : windows[group_of[i]])
      rects.push_back(
          vision::DotFitWindow((*measured)[w.image].dots[w.dot], img.size(), dot_options));
    contribution[i] = vision::BackgroundContribution(img, (*measured)[i].dots, rects, dot_options);
    for (const auto& d : (*measured)[i].dots)
      own[i].push_back(
          vision::ReadDotSignal(img, vision::DotFitWindow(d, img.size(), dot_options)));
  });
  for (size_t g = 0; g < groups.size(); ++g) {
    if (windows[g].empty()) continue;
    bool same_size = true;
    cv::Size size;
    for (size_t i : groups[g]) {
      if (contribution[i].empty()) continue;
      if (size.empty()) size = sizes[i];
      same_size = same_size && sizes[i] == size;
    }
    if (!same_size) continue;
    for (size_t w = 0; w < windows[g].size(); ++w) {
      vision::BackgroundPatch bg;
      for (size_t i : groups[g])
        if (!contribution[i].empty()) bg.Add(contribution[i][w]);
      const Window& win = windows[g][w];
      vision::RefineDotOnBackground(own[win.image][win.dot], bg, dot_options,
                                    &(*measured)[win.image].dots[win.dot]);
    }
  }
}

// Repeated exposures (PipelineOptions::average_exposures): `members[file]` lists the frames
// averaged into the kept frame `file` (itself first).
struct Exposures {
  std::map<std::string, std::vector<std::string>> members;
  dataset::Recording rec;  // one frame per scene (the first exposure's entry)
};

Exposures CollapseExposures(const dataset::Recording& in) {
  Exposures e;
  dataset::Recording& r = e.rec;
  r = in;  // everything but the frame lists (the solver reads no Hall data; a copy is cheap)
  r.step1.clear();
  r.step2.clear();
  auto sorted = [](std::vector<int> v) {
    std::sort(v.begin(), v.end());
    return v;
  };
  std::map<std::pair<int, std::vector<int>>, size_t> step1_scene;
  for (const auto& f : in.step1) {
    const auto [it, added] =
        step1_scene.emplace(std::make_pair(f.pose, sorted(f.beams)), r.step1.size());
    if (added) r.step1.push_back(f);
    e.members[r.step1[it->second].file].push_back(f.file);
  }
  std::map<std::tuple<int, std::vector<int>, std::vector<int>>, size_t> step2_scene;
  for (const auto& f : in.step2) {
    const auto key = std::make_tuple(static_cast<int>(f.kind), sorted(f.triggers), sorted(f.beams));
    const auto [it, added] = step2_scene.emplace(key, r.step2.size());
    if (added) r.step2.push_back(f);
    e.members[r.step2[it->second].file].push_back(f.file);
  }
  return e;
}

// The pixel mean of `files` (8-bit input: 16-bit output scaled by 257, so that full scale stays
// full scale and a pixel saturated in every exposure reads as saturated; 16-bit: 16-bit).
cv::Mat AverageExposures(const std::vector<std::string>& files, const ImageLoader& load) {
  cv::Mat sum, first;
  for (const auto& f : files) {
    const cv::Mat img = load(f);
    if (img.empty()) throw SolveError(f + ": cannot read the image");
    if (first.empty()) {
      first = img;
      sum = cv::Mat::zeros(img.size(), CV_MAKETYPE(CV_32F, img.channels()));
    } else if (img.size() != first.size() || img.type() != first.type()) {
      throw SolveError(f + ": an exposure of the same scene as " + files[0] +
                       " but its size or pixel format differs");
    }
    cv::Mat fl;
    img.convertTo(fl, CV_32F);
    sum += fl;
  }
  const double k = static_cast<double>(files.size());
  cv::Mat out;
  sum.convertTo(out, CV_MAKETYPE(CV_16U, first.channels()),
                first.depth() == CV_8U ? 257.0 / k : 1.0 / k);
  return out;
}

}  // namespace

ImageMeasurement MeasureImage(const cv::Mat& img, const std::vector<vision::BoardSize>& boards,
                              const vision::DotOptions& dot_options,
                              const vision::CheckerboardOptions& board_options) {
  // OpenCV's detectors draw from the calling thread's cv::theRNG(): reseed it per image so
  // that an image's measurement does not depend on which images its thread measured before.
  cv::theRNG() = cv::RNG(0x6d736d63616cULL);
  ImageMeasurement m;
  m.image_size = img.size();
  m.channels = img.channels();
  m.depth_bits = img.depth() == CV_16U ? 16 : 8;
  if (boards.size() == 1) {
    m.board_attempts.resize(1);
    m.boards = {
        vision::DetectCheckerboard(img, boards[0], board_options, cv::Mat(), &m.board_attempts[0])};
  } else {
    m.boards = vision::DetectCheckerboards(img, boards, board_options, &m.board_attempts);
  }
  m.dots = vision::DetectDots(img, dot_options, &m.dot_rejections);
  return m;
}

ImageMeasurement MeasureFrame(const cv::Mat& img, const std::vector<vision::BoardSize>& sizes,
                              int expected, const PipelineOptions& o) {
  ImageMeasurement m = MeasureImage(img, sizes, o.dots, o.boards);
  const auto& host = sizes.size() == 2 ? m.boards[1] : m.boards[0];
  if (!host) return m;
  RegionRejections rej;
  const size_t first = DotsOnHostPlane(m.dots, m, sizes, o, &rej).size();
  m.dots_on_plane = first;
  if (!o.adaptive_dots || expected <= 0 || first >= static_cast<size_t>(expected)) return m;
  const vision::DotOptions adaptive = vision::AdaptiveDotOptions(img, host->square_px, o.dots);
  vision::DotRejections rej2;
  auto dots2 = vision::DetectDots(img, adaptive, &rej2);
  // A low threshold also passes noise, compression and board residue: the laser's spots in
  // one frame are alike, so blobs far fainter than the frame's brightest on the plane go.
  RegionRejections rej3;
  double brightest = 0;
  for (const auto& d : DotsOnHostPlane(dots2, m, sizes, o, &rej3))
    brightest = std::max(brightest, d.peak);
  // A clipped spot's peak is capped by the headroom over its background (a light square,
  // gamma): it is compared with the smaller of the brightest and that headroom.
  const double full = img.depth() == CV_16U ? 65535.0 : 255.0;
  const size_t before_peak = dots2.size();
  dots2.erase(
      std::remove_if(dots2.begin(), dots2.end(),
                     [&](const vision::Dot& d) {
                       // Only a clipped spot is excused by its headroom.
                       const bool clipped = d.peak_level >= std::min(d.plateau_level, 0.98 * full);
                       const double headroom = full - (d.peak_level - d.peak);
                       const double reference = clipped ? std::min(brightest, headroom) : brightest;
                       return d.peak < o.adaptive_min_relative_peak * reference;
                     }),
      dots2.end());
  rej2.too_faint = static_cast<int>(before_peak - dots2.size());
  // The second pass adds to the first: its dots that no first-pass dot's blob already covers
  // (a larger kernel can merge or lose a spot the first pass had).
  for (const auto& d : m.dots)
    if (std::none_of(dots2.begin(), dots2.end(), [&](const vision::Dot& e) {
          return (e.px - d.px).norm() < 0.5 * std::max(d.blob_box.width, d.blob_box.height) + 2;
        }))
      dots2.push_back(d);
  std::sort(dots2.begin(), dots2.end(), [](const vision::Dot& a, const vision::Dot& b) {
    return std::make_pair(a.blob_box.y, a.blob_box.x) < std::make_pair(b.blob_box.y, b.blob_box.x);
  });
  rej3 = {};
  const size_t second = DotsOnHostPlane(dots2, m, sizes, o, &rej3).size();

  m.second_pass_on_plane = static_cast<int>(second);
  if (second <= first || second > static_cast<size_t>(expected + o.max_surplus_dots)) return m;
  m.dots = std::move(dots2);
  m.dot_rejections = rej2;
  m.adaptive_dots = true;
  std::ostringstream what;
  what << "dots from the image's own scale: threshold " << adaptive.threshold_fraction
       << " of full scale, top-hat " << adaptive.background_kernel_px << " px, min "
       << adaptive.min_pixels << " px (" << first << " -> " << second << " on the plane)";
  m.dot_settings = what.str();
  m.dots_on_plane = second;
  return m;
}

SolveOutput SolveRecording(const dataset::Recording& input, const ImageLoader& input_load,
                           const PipelineOptions& o) {
  if (const std::string e = o.Validate(); !e.empty()) throw SolveError("PipelineOptions: " + e);
  if (const std::string e = input.camera.Validate(); !e.empty())
    throw SolveError("camera.yaml: " + e);
  SolveOutput out;
  // Repeated exposures of a scene become one averaged frame.
  std::optional<Exposures> exposures;
  if (o.average_exposures) {
    exposures = CollapseExposures(input);
    size_t averaged = 0, scenes = 0;
    for (const auto& [file, m] : exposures->members)
      if (m.size() > 1) {
        averaged += m.size();
        ++scenes;
      }
    if (scenes == 0)
      exposures.reset();
    else
      out.notes.push_back("exposures: " + std::to_string(averaged) + " frames are repeated " +
                          "exposures of " + std::to_string(scenes) +
                          " scene(s); each scene's exposures were averaged and measured as one "
                          "image (named by its first frame)");
  }
  const dataset::Recording& rec = exposures ? exposures->rec : input;
  // With averaged scenes every image is handed on as 16-bit (8-bit scaled by 257), so that the
  // images whose backgrounds are pooled (RefineDotsOnBackgrounds) share one scale.
  const ImageLoader load = [&](const std::string& file) -> cv::Mat {
    if (!exposures) return input_load(file);
    const auto it = exposures->members.find(file);
    if (it != exposures->members.end() && it->second.size() > 1)
      return AverageExposures(it->second, input_load);
    cv::Mat img = input_load(file);
    if (img.depth() != CV_8U) return img;
    cv::Mat wide;
    img.convertTo(wide, CV_MAKETYPE(CV_16U, img.channels()), 257.0);
    return wide;
  };
  // Per measured (collapsed) frame: what was measured and decided (results/detections.csv).
  std::vector<FrameDetection> det;
  // Expands `det` to one row per frame of the input (exposures share their scene's row) and
  // marks the dropped ones.
  auto finish_detections = [&](SolveOutput* o_out) {
    std::map<std::string, std::string> dropped_reason;
    for (const auto& d : out.dropped) dropped_reason.emplace(d.file, d.reason);
    std::map<std::string, const FrameDetection*> by_scene;
    for (const auto& d : det) by_scene[d.file] = &d;
    o_out->detections.clear();
    auto add = [&](const std::string& file, const std::string& step) {
      std::string scene = file;
      if (exposures)
        for (const auto& [first, members] : exposures->members)
          if (std::find(members.begin(), members.end(), file) != members.end()) scene = first;
      FrameDetection d;
      if (const auto it = by_scene.find(scene); it != by_scene.end()) d = *it->second;
      d.file = file;
      d.step = step;
      d.scene = scene;
      if (const auto it = dropped_reason.find(scene); it != dropped_reason.end()) {
        // "... frame used for the sliding board only": used in part.
        if (it->second.find("used for the sliding board only") != std::string::npos) {
          d.used = true;
          d.partial = true;
          d.note = it->second;
        } else {
          d.used = false;
          d.reason = it->second;
        }
      } else if (d.dots_found >= 0) {
        d.used = true;
      } else if (d.reason.empty()) {
        d.used = false;
        d.reason = "not reached: the solve stopped before this frame was used";
      }
      o_out->detections.push_back(std::move(d));
    };
    for (const auto& f : input.step1) add(f.file, "step1");
    for (const auto& f : input.step2) add(f.file, "step2");
  };
  // Errors carry the frames dropped so far (they usually explain the failure) and the
  // detections up to the failure.
  auto fail = [&](const std::string& what) {
    std::string msg = what;
    if (!out.dropped.empty()) {
      msg += "; frames dropped:";
      for (const auto& d : out.dropped) msg += " [" + d.file + ": " + d.reason + "]";
    }
    auto partial = std::make_shared<SolveOutput>();
    partial->dropped = out.dropped;
    partial->notes = out.notes;
    finish_detections(partial.get());
    return SolveError(msg, partial);
  };
  // Beams.
  std::map<int, int> beam_index;
  std::vector<int> beam_ids;
  std::vector<bool> is_estimate;
  for (const auto& b : rec.beams) {
    beam_index[b.id] = static_cast<int>(beam_ids.size());
    beam_ids.push_back(b.id);
    is_estimate.push_back(b.role == dataset::BeamRole::kEstimate);
  }
  const int num_beams = static_cast<int>(beam_ids.size());
  auto beam_of = [&](int id, const std::string& file) {
    const auto it = beam_index.find(id);
    if (it == beam_index.end())
      throw fail("session.yaml: frame " + file + " lists beam " + std::to_string(id) +
                 " which is not in beams");
    return it->second;
  };
  Observations obs;
  obs.camera = rec.camera;
  const auto world_pts = BoardPoints(rec.world_board);
  const auto sliding_pts = BoardPoints(rec.sliding_board);
  const vision::BoardSize world_size{rec.world_board.cols, rec.world_board.rows};
  const vision::BoardSize sliding_size{rec.sliding_board.cols, rec.sliding_board.rows};
  // Boards and dots of every image first (parallel over images, OpenCV serial inside).
  std::vector<ImageMeasurement> measured;
  {
    const OpenCvSerial serial;
    std::vector<std::string> files;
    std::vector<std::vector<vision::BoardSize>> asks;
    for (const auto& f : rec.step1) {
      files.push_back(f.file);
      asks.push_back({world_size, sliding_size});
    }
    for (const auto& f : rec.step2) {
      files.push_back(f.file);
      asks.push_back({world_size});
    }
    try {
      std::vector<int> expected;
      for (const auto& f : rec.step1) expected.push_back(static_cast<int>(f.beams.size()));
      for (const auto& f : rec.step2)
        expected.push_back(static_cast<int>(
            (f.kind == Step2Kind::kNeutral ? 1 : f.triggers.size()) * f.beams.size()));
      measured = MeasureImages(files, asks, load, o, expected);
      if (o.dots.centre == vision::DotCentre::kGaussianFit) {
        std::vector<std::vector<size_t>> static_groups;
        std::map<int, size_t> group_of_pose;
        for (size_t i = 0; i < rec.step1.size(); ++i) {
          auto [it, added] = group_of_pose.emplace(rec.step1[i].pose, static_groups.size());
          if (added) static_groups.emplace_back();
          static_groups[it->second].push_back(i);
        }
        static_groups.emplace_back();
        for (size_t i = 0; i < rec.step2.size(); ++i)
          static_groups.back().push_back(rec.step1.size() + i);
        RefineDotsOnBackgrounds(static_groups, files, load, o.dots, o.image_threads, &measured);
        int on_background = 0, top_hat = 0, centroid = 0;
        for (const auto& m : measured)
          for (const auto& d : m.dots)
            (d.on_background ? on_background : d.fitted ? top_hat : centroid)++;
        out.notes.push_back("dots: " + std::to_string(on_background) +
                            " fitted over a background measured in other images, " +
                            std::to_string(top_hat) +
                            " over the top-hat (no dot-free view of their window), " +
                            std::to_string(centroid) + " weighted centroids (fit failed)");
      }
    } catch (const SolveError& e) {
      throw fail(e.what());
    }
  }
  for (size_t i = 0; i < measured.size(); ++i) {
    const bool first = i < rec.step1.size();
    FrameDetection d;
    d.file = first ? rec.step1[i].file : rec.step2[i - rec.step1.size()].file;
    d.step = first ? "step1" : "step2";
    const std::vector<std::string> names =
        first ? std::vector<std::string>{"world", "sliding"} : std::vector<std::string>{"world"};
    for (size_t b = 0; b < measured[i].boards.size(); ++b) {
      FrameDetection::Board board;
      board.name = names[b];
      if (const auto& found = measured[i].boards[b]) {
        board.found = true;
        board.method = vision::ToString(found->method);
        board.square_px = found->square_px;
        board.corners_px = found->corners_px;
      }
      d.boards.push_back(board);
    }
    d.blobs = static_cast<int>(measured[i].dots.size());
    if (measured[i].adaptive_dots) d.note = measured[i].dot_settings;
    d.rejected = measured[i].dot_rejections;
    det.push_back(std::move(d));
  }
  size_t next_measured = 0;
  auto to_obs = [](const vision::Dot& d) { return PixelObs{d.px, d.cov_px2}; };

  // ---------------- Step 1: sliding boards, beams ----------------
  struct S1 {
    std::string file;
    int pose = 0;  // remapped
    std::vector<int> beams;
    std::vector<vision::Dot> dots;
    Rigid3d c1_from_sliding;
    std::vector<Eigen::Vector3d> dots_in_world;
    std::vector<int> label;  // beam index per dot, -1 unknown
  };
  std::vector<S1> s1;
  std::vector<std::vector<char>> corners_clear;  // per obs.corners entry: corner clear of dots
  std::map<int, int> pose_remap;
  std::optional<Rigid3d> c1_from_world;
  size_t c1_corners = 0;
  for (const auto& f : rec.step1) {
    FrameDetection& fd = det[next_measured];
    const ImageMeasurement& m = measured[next_measured++];
    const auto& boards = m.boards;
    fd.dots_expected = static_cast<int>(f.beams.size());
    if (!boards[1]) {
      out.dropped.push_back(
          {f.file, "sliding board (" + SizeText(rec.sliding_board) + ") not found"});
      continue;
    }
    RegionRejections region;
    auto dots = DotsOnBoard(m.dots, *boards[1], sliding_size, o.step1_dot_margin_squares, o,
                            boards[0] ? vision::SquaresOutline(*boards[0], world_size, 0.5)
                                      : std::vector<Eigen::Vector2d>{},
                            &region);
    RecordDots(dots, m.dots, region, &fd);
    if (f.beams.empty() && !dots.empty()) {
      out.notes.push_back(f.file + ": background frame (every beam blocked) shows " +
                          std::to_string(dots.size()) + " dot-like blob(s); ignored");
      dots.clear();
    }
    if (dots.size() > f.beams.size()) {
      // Surplus blobs (checkerboard-junction residue): keep the roundest, say so.
      auto elongation = [](const vision::Dot& d) {
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(d.cov_px2);
        return es.eigenvalues()(1) / std::max(es.eigenvalues()(0), 1e-12);
      };
      std::stable_sort(dots.begin(), dots.end(),
                       [&](const auto& a, const auto& b) { return elongation(a) < elongation(b); });
      out.notes.push_back(f.file + ": kept the " + std::to_string(f.beams.size()) +
                          " roundest of " + std::to_string(dots.size()) + " blobs");
      dots.resize(f.beams.size());
    }
    if (dots.size() != f.beams.size()) {
      out.dropped.push_back({f.file, "found " + std::to_string(dots.size()) +
                                         " laser dots, expected " + std::to_string(f.beams.size()) +
                                         " (one per listed beam)"});
      continue;
    }
    const auto c1s = SolvePlanarPnP(rec.camera, sliding_pts, boards[1]->corners_px);
    if (!c1s) {
      out.dropped.push_back({f.file, "PnP of the sliding board failed"});
      continue;
    }
    fd.boards[1].corner_rms_px =
        ReprojectionRms(rec.camera, *c1s, sliding_pts, boards[1]->corners_px);
    if (boards[0]) {
      if (auto t = SolvePlanarPnP(rec.camera, world_pts, boards[0]->corners_px))
        fd.boards[0].corner_rms_px =
            ReprojectionRms(rec.camera, *t, world_pts, boards[0]->corners_px);
      obs.corners.push_back({BoardView::kC1World, -1, world_pts, boards[0]->corners_px});
      corners_clear.push_back(CornersClearOfDots(*boards[0], m.dots));
      if (world_pts.size() > c1_corners) {
        if (auto t = SolvePlanarPnP(rec.camera, world_pts, boards[0]->corners_px)) {
          c1_from_world = t;
          c1_corners = world_pts.size();
        }
      }
    } else {
      out.notes.push_back(f.file +
                          ": world board not found; frame used for the sliding board only");
      fd.partial = true;
      fd.note = "world board not found: used for the sliding board only";
    }
    const int pose = pose_remap.emplace(f.pose, static_cast<int>(pose_remap.size())).first->second;
    obs.corners.push_back({BoardView::kC1Sliding, pose, sliding_pts, boards[1]->corners_px});
    corners_clear.push_back(CornersClearOfDots(*boards[1], m.dots));
    S1 s;
    s.file = f.file;
    s.pose = pose;
    for (int id : f.beams) s.beams.push_back(beam_of(id, f.file));
    s.dots = dots;
    s.c1_from_sliding = *c1s;
    s.label.assign(dots.size(), -1);
    s1.push_back(std::move(s));
  }
  if (!c1_from_world)
    throw fail("step1: the world board (" + SizeText(rec.world_board) +
               ") was not found in any step 1 image");
  obs.num_poses = static_cast<int>(pose_remap.size());
  const Rigid3d world_from_c1 = c1_from_world->Inverse();
  Eigen::Vector3d sliding_z = Eigen::Vector3d::Zero();
  std::vector<Rigid3d> world_from_pose(obs.num_poses);
  for (auto& s : s1) {
    world_from_pose[s.pose] = world_from_c1 * s.c1_from_sliding;
    sliding_z += world_from_pose[s.pose].rotation * Eigen::Vector3d::UnitZ();
    for (const auto& d : s.dots) {
      const auto p = BackProjectToBoard(rec.camera, s.c1_from_sliding, d.px);
      s.dots_in_world.push_back(p ? world_from_pose[s.pose] * *p : Eigen::Vector3d::Zero());
    }
  }
  // Identification frames: one beam, one dot.
  std::vector<std::vector<Eigen::Vector3d>> beam_points(num_beams);
  std::vector<std::vector<int>> beam_poses(num_beams);
  std::vector<bool> done(s1.size(), false);
  for (size_t k = 0; k < s1.size(); ++k) {
    if (s1[k].beams.size() != 1) continue;
    s1[k].label[0] = s1[k].beams[0];
    beam_points[s1[k].beams[0]].push_back(s1[k].dots_in_world[0]);
    beam_poses[s1[k].beams[0]].push_back(s1[k].pose);
    done[k] = true;
  }
  // Other frames, nearest to already labelled poses first: predict each beam's dot on the
  // frame's sliding plane (line through >= 2 poses, else the labelled point) and take the best
  // permutation.
  for (;;) {
    int next = -1;
    double next_dist = 1e300;
    for (size_t k = 0; k < s1.size(); ++k) {
      if (done[k]) continue;
      double dist = 1e300;
      for (int b : s1[k].beams)
        for (size_t q = 0; q < beam_points[b].size(); ++q)
          dist =
              std::min(dist, (world_from_pose[s1[k].pose].translation - beam_points[b][q]).norm());
      if (dist < next_dist) {
        next_dist = dist;
        next = static_cast<int>(k);
      }
    }
    if (next < 0) break;
    S1& s = s1[next];
    done[next] = true;
    std::vector<Eigen::Vector3d> pred;
    bool ok = true;
    const Plane plane_w =
        geometry::TransformPlane(world_from_pose[s.pose], Plane{Eigen::Vector3d::UnitZ(), 0});
    for (int b : s.beams) {
      if (beam_points[b].empty()) {
        ok = false;
        break;
      }
      std::set<int> distinct(beam_poses[b].begin(), beam_poses[b].end());
      if (distinct.size() >= 2) {
        const auto x = geometry::IntersectLinePlane(geometry::FitLine(beam_points[b]), plane_w);
        pred.push_back(x ? *x : beam_points[b].back());
      } else {
        pred.push_back(beam_points[b].back());
      }
    }
    if (!ok) {
      out.dropped.push_back({s.file,
                             "cannot tell its beams apart: a listed beam has no "
                             "identification frame"});
      continue;
    }
    const int n = static_cast<int>(s.dots.size());
    const auto perm = BestPermutation(
        n, [&](int i, int slot) { return (pred[i] - s.dots_in_world[slot]).squaredNorm(); });
    for (int i = 0; i < n; ++i) {
      s.label[perm[i]] = s.beams[i];
      beam_points[s.beams[i]].push_back(s.dots_in_world[perm[i]]);
      beam_poses[s.beams[i]].push_back(s.pose);
    }
  }
  // Label check: fit each beam to all its labelled dots; while the farthest dot exceeds
  // kMaxBeamLineResidualMm, drop its whole frame's labels (a wrong label pulls the line but
  // stays the farthest point) and refit. Dropped frames still serve the sliding board pose.
  for (;;) {
    std::vector<std::vector<Eigen::Vector3d>> pts(num_beams);
    std::vector<std::set<int>> poses(num_beams);
    for (const auto& s : s1)
      for (size_t i = 0; i < s.dots.size(); ++i)
        if (s.label[i] >= 0) {
          pts[s.label[i]].push_back(s.dots_in_world[i]);
          poses[s.label[i]].insert(s.pose);
        }
    std::vector<std::optional<Line>> fit(num_beams);
    for (int b = 0; b < num_beams; ++b)
      if (poses[b].size() >= 2) fit[b] = FitBeam(pts[b], sliding_z);
    int worst_frame = -1, worst_beam = -1;
    double worst = kMaxBeamLineResidualMm;
    for (size_t k = 0; k < s1.size(); ++k)
      for (size_t i = 0; i < s1[k].dots.size(); ++i) {
        const int b = s1[k].label[i];
        if (b < 0 || !fit[b]) continue;
        const Line& l = *fit[b];
        const double d = (s1[k].dots_in_world[i].cross(l.v) - l.m).norm() / l.v.norm();
        if (d > worst) {
          worst = d;
          worst_frame = static_cast<int>(k);
          worst_beam = b;
        }
      }
    if (worst_frame < 0) break;
    S1& bad = s1[worst_frame];
    std::ostringstream why;
    why << "its dot labelled beam " << beam_ids[worst_beam] << " lies " << worst
        << " mm from that beam's line (> " << kMaxBeamLineResidualMm
        << " mm): dot-to-beam labels inconsistent; frame used for the sliding board only";
    out.dropped.push_back({bad.file, why.str()});
    bad.label.assign(bad.dots.size(), -1);
  }
  for (auto& pts : beam_points) pts.clear();
  for (auto& ps : beam_poses) ps.clear();
  for (const auto& s : s1)
    for (size_t i = 0; i < s.dots.size(); ++i)
      if (s.label[i] >= 0) {
        beam_points[s.label[i]].push_back(s.dots_in_world[i]);
        beam_poses[s.label[i]].push_back(s.pose);
      }
  for (const auto& s : s1)
    for (size_t i = 0; i < s.dots.size(); ++i)
      if (s.label[i] >= 0) obs.sliding_dots.push_back({s.pose, s.label[i], to_obs(s.dots[i])});
  std::vector<Line> beams0(num_beams);
  for (int b = 0; b < num_beams; ++b) {
    std::set<int> distinct(beam_poses[b].begin(), beam_poses[b].end());
    if (distinct.size() < 2)
      throw fail("step1: beam " + std::to_string(beam_ids[b]) + " has dots on " +
                 std::to_string(distinct.size()) + " sliding pose(s); needs >= 2");
    beams0[b] = FitBeam(beam_points[b], sliding_z);
  }
  obs.num_beams = num_beams;

  // ---------------- Step 2: world board, reflected dots, groups ----------------
  struct S2 {
    const dataset::Step2Frame* frame = nullptr;
    std::vector<vision::Dot> dots;
    std::vector<Eigen::Vector3d> dots_in_world;
    std::vector<bool> near_edge;
    bool partial = false;  // fewer dots than triggers x beams
  };
  std::vector<S2> s2;
  std::optional<Rigid3d> c2_from_world;
  for (const auto& f : rec.step2) {
    FrameDetection& fd = det[rec.step1.size() + (&f - rec.step2.data())];
    const ImageMeasurement& m = measured[rec.step1.size() + (&f - rec.step2.data())];
    const auto& board = m.boards[0];
    const size_t triggers = f.kind == Step2Kind::kNeutral ? 1 : f.triggers.size();
    const size_t expected = triggers * f.beams.size();
    fd.dots_expected = static_cast<int>(expected);
    if (!board) {
      out.dropped.push_back({f.file, "world board (" + SizeText(rec.world_board) + ") not found"});
      continue;
    }
    RegionRejections region;
    const auto dots =
        DotsOnBoard(m.dots, *board, world_size, o.step2_dot_margin_squares, o, {}, &region);
    RecordDots(dots, m.dots, region, &fd);
    if (auto t = SolvePlanarPnP(rec.camera, world_pts, board->corners_px))
      fd.boards[0].corner_rms_px = ReprojectionRms(rec.camera, *t, world_pts, board->corners_px);
    // Fewer dots than expected (two spots merged, one off the board): the triggers whose dots
    // are all there are still grouped, under a tighter tolerance (below). More (stray blobs on
    // the world plane): the mirror-plane consistency picks the dots.
    const bool partial = dots.size() < expected && dots.size() >= 2;
    const bool surplus =
        dots.size() > expected && dots.size() <= expected + static_cast<size_t>(o.max_surplus_dots);
    if (surplus) {
      out.notes.push_back(f.file + ": " + std::to_string(dots.size()) + " dot-like blobs, " +
                          std::to_string(expected) +
                          " expected; the reflection grouping picks the consistent ones");
      fd.note = std::to_string(dots.size() - expected) + " surplus blob(s) left out by grouping";
    }
    if (dots.size() != expected && !partial && !surplus) {
      out.dropped.push_back({f.file, "found " + std::to_string(dots.size()) +
                                         " laser dots, expected " + std::to_string(expected) +
                                         " (" + std::to_string(triggers) + " trigger(s) x " +
                                         std::to_string(f.beams.size()) + " beam(s))"});
      continue;
    }
    obs.corners.push_back({BoardView::kC2World, -1, world_pts, board->corners_px});
    corners_clear.push_back(CornersClearOfDots(*board, m.dots));
    if (!c2_from_world) c2_from_world = SolvePlanarPnP(rec.camera, world_pts, board->corners_px);
    s2.push_back({&f, dots, {}, {}, partial});
  }
  if (!c2_from_world)
    throw fail("step2: no usable step 2 image (the world board (" + SizeText(rec.world_board) +
               ") must be found and the frame's laser dots counted)");
  // Dots whose spot (blob radius plus half the top-hat kernel) reaches a square edge of the
  // world board: the background there biases the centroid (docs/solver.md, "Dot covariance").
  auto near_edge = [&](const vision::Dot& d, const Eigen::Vector3d& p) {
    const auto p1 = BackProjectToBoard(rec.camera, *c2_from_world, d.px + Eigen::Vector2d(1, 0));
    if (!p1) return false;
    const double mm_per_px = (*p1 - p).norm();
    const double reach_mm =
        (std::sqrt(d.num_pixels / M_PI) + 0.5 * o.dots.background_kernel_px) * mm_per_px;
    const double sq = rec.world_board.square_mm;
    auto to_line = [&](double v) {
      const double m = v - sq * std::floor(v / sq);
      return std::min(m, sq - m);
    };
    return std::min(to_line(p.x()), to_line(p.y())) < reach_mm;
  };
  for (auto& s : s2)
    for (const auto& d : s.dots) {
      const auto p = BackProjectToBoard(rec.camera, *c2_from_world, d.px);
      s.dots_in_world.push_back(p.value_or(Eigen::Vector3d::Zero()));
      s.near_edge.push_back(p && !d.on_background && near_edge(d, *p));
    }
  // recovered: groups built by elimination from the estimate beams' dots alone (the frame's
  // other triggers complete, its held-out dots missing); kept only if the drive-phase model
  // agrees (after the trigger assignment).
  std::vector<Group> groups, recovered;
  for (size_t fi = 0; fi < s2.size(); ++fi) {
    const S2& s = s2[fi];
    std::vector<int> e, v;
    for (int id : s.frame->beams)
      (is_estimate[beam_of(id, s.frame->file)] ? e : v).push_back(beam_of(id, s.frame->file));
    if (e.size() < 2) {
      out.dropped.push_back({s.frame->file, "needs >= 2 beams with role estimate"});
      continue;
    }
    const int n = static_cast<int>(s.dots.size());
    const size_t want = s.frame->kind == Step2Kind::kNeutral ? 1 : s.frame->triggers.size();
    const double max_score =
        s.partial ? std::min(o.max_group_residual_px, o.partial_frame_group_residual_px)
                  : o.max_group_residual_px;
    struct Candidate {
      double score;
      std::map<int, int> dot_of_beam;
      Plane plane;
    };
    // The plane through the estimate beams' dots `dots` (dots[i] for beam e[i]); score = sum of
    // their pixel distances to its predictions.
    auto plane_of = [&](const std::vector<int>& dots) -> std::optional<Candidate> {
      std::vector<Line> lines;
      std::vector<Eigen::Vector3d> xs;
      for (size_t i = 0; i < e.size(); ++i) {
        lines.push_back(beams0[e[i]]);
        xs.push_back(s.dots_in_world[dots[i]]);
      }
      const auto plane = InitialMirrorPlane(lines, xs);
      if (!plane) return std::nullopt;
      Candidate c{0, {}, *plane};
      for (size_t i = 0; i < e.size(); ++i) {
        const auto px = PredictReflectedDot(rec.camera, *c2_from_world, beams0[e[i]], *plane);
        if (!px) return std::nullopt;
        c.score += (*px - s.dots[dots[i]].px).norm();
        c.dot_of_beam[e[i]] = dots[i];
      }
      return c;
    };
    std::vector<Candidate> cands;
    std::vector<int> tuple(e.size(), 0);
    std::function<void(size_t)> rec_tuple = [&](size_t k) {
      if (k == e.size()) {
        auto found = plane_of(tuple);
        if (!found) return;
        Candidate& c = *found;
        for (int b : v) {
          const auto px = PredictReflectedDot(rec.camera, *c2_from_world, beams0[b], c.plane);
          if (!px) return;
          int best = -1;
          for (int d = 0; d < n; ++d) {
            if (std::find(tuple.begin(), tuple.end(), d) != tuple.end()) continue;
            if (best < 0 || (*px - s.dots[d].px).norm() < (*px - s.dots[best].px).norm()) best = d;
          }
          if (best < 0) return;
          c.score += (*px - s.dots[best].px).norm();
          c.dot_of_beam[b] = best;
        }
        c.score /= static_cast<double>(c.dot_of_beam.size());
        cands.push_back(std::move(c));
        return;
      }
      for (int d = 0; d < n; ++d) {
        if (std::find(tuple.begin(), tuple.begin() + k, d) != tuple.begin() + k) continue;
        tuple[k] = d;
        rec_tuple(k + 1);
      }
    };
    rec_tuple(0);
    std::sort(cands.begin(), cands.end(),
              [](const Candidate& a, const Candidate& b) { return a.score < b.score; });
    std::vector<bool> used(n, false);
    std::vector<Group> accepted;
    for (const auto& c : cands) {
      if (accepted.size() == want || c.score > max_score) break;
      bool free = true;
      for (const auto& [b, d] : c.dot_of_beam) free = free && !used[d];
      std::set<int> distinct;
      for (const auto& [b, d] : c.dot_of_beam) distinct.insert(d);
      if (!free || distinct.size() != c.dot_of_beam.size()) continue;
      for (const auto& [b, d] : c.dot_of_beam) used[d] = true;
      accepted.push_back(Group{static_cast<int>(fi), c.dot_of_beam, c.plane, 0});
    }
    // One trigger short, and exactly the estimate beams' number of dots left over: those dots
    // are that trigger's (elimination) and the held-out ones are missing. Its plane comes from
    // them alone; with two estimate beams a wrong beam pairing can fit as well, so the group is
    // tentative until the drive-phase model has checked its angles (below).
    if (s.partial && s.frame->kind != Step2Kind::kNeutral && accepted.size() + 1 == want &&
        !v.empty()) {
      std::vector<int> left;
      for (int d = 0; d < n; ++d)
        if (!used[d]) left.push_back(d);
      if (left.size() == e.size()) {
        std::optional<Candidate> best;
        std::sort(left.begin(), left.end());
        do {
          auto c = plane_of(left);
          if (!c) continue;
          c->score /= static_cast<double>(e.size());
          if (!best || c->score < best->score) best = std::move(c);
        } while (std::next_permutation(left.begin(), left.end()));
        if (best && best->score <= max_score)
          recovered.push_back(Group{static_cast<int>(fi), best->dot_of_beam, best->plane, 0});
      }
    }
    const bool tentative = !recovered.empty() && recovered.back().frame == static_cast<int>(fi);
    if (s.partial && (!accepted.empty() || tentative)) {
      FrameDetection& pfd = det[rec.step1.size() + (s.frame - rec.step2.data())];
      pfd.partial = true;
      pfd.note = std::to_string(accepted.size()) + " of " + std::to_string(want) +
                 " trigger(s) kept (" + std::to_string(n) + " of " +
                 std::to_string(want * s.frame->beams.size()) + " dots found)";
      out.notes.push_back(s.frame->file + ": " + std::to_string(n) + " of " +
                          std::to_string(want * s.frame->beams.size()) + " laser dots found; " +
                          std::to_string(accepted.size()) + " of " + std::to_string(want) +
                          " trigger(s) grouped and kept");
    } else if (accepted.size() != want) {
      out.dropped.push_back(
          {s.frame->file,
           (s.partial ? "found " + std::to_string(n) + " of " +
                            std::to_string(want * s.frame->beams.size()) + " laser dots and "
                      : std::string()) +
               "could group only " + std::to_string(accepted.size()) + " of " +
               std::to_string(want) + " trigger(s) into consistent mirror planes"});
      continue;
    }
    for (auto& g : accepted) groups.push_back(std::move(g));
  }
  // Provisional home frame for the trigger assignment.
  std::vector<Plane> neutral_planes, fast_planes;
  for (const auto& g : groups) {
    if (s2[g.frame].frame->kind == Step2Kind::kNeutral) neutral_planes.push_back(g.plane);
    if (s2[g.frame].frame->kind == Step2Kind::kFastOnly) fast_planes.push_back(g.plane);
  }
  Eigen::Vector3d n0 = Eigen::Vector3d::Zero();
  for (const auto& p : neutral_planes.empty() ? std::vector<Plane>{} : neutral_planes) n0 += p.n;
  if (neutral_planes.empty())
    for (const auto& g : groups) n0 += g.plane.n;
  if (groups.empty()) throw fail("step2: no usable frame with reflected dots");
  n0.normalize();
  const Eigen::Vector3d fast0 =
      fast_planes.size() >= 2 ? geometry::FastAxisFromPlanes(fast_planes) : TangentBasis(n0).col(0);
  const Rigid3d provisional = geometry::MirrorHomeFrame(n0, fast0, Eigen::Vector3d::Zero());
  auto angles_of = [&](const Plane& p) {
    const auto pose = geometry::PoseFromWorldPlane(provisional, p);
    return Eigen::Vector2d(pose.alpha_rad * kRadToDeg, pose.beta_rad * kRadToDeg);
  };
  {
    std::vector<TriggerFrame> tframes(s2.size());
    std::vector<TriggerGroup> tgroups;
    std::vector<int> multi_index;
    std::map<int, double> t_of_j;
    for (const auto& t : rec.triggers) t_of_j[t.j] = t.t_s;
    for (size_t f = 0; f < s2.size(); ++f) {
      tframes[f].slow_on = s2[f].frame->kind == Step2Kind::kScan;
      for (int j : s2[f].frame->triggers) {
        if (!t_of_j.count(j))
          throw fail("session.yaml: frame " + s2[f].frame->file + " lists trigger " +
                     std::to_string(j) + " which is not in triggers");
        tframes[f].t_s.push_back(t_of_j[j]);
      }
    }
    for (size_t g = 0; g < groups.size(); ++g) {
      const auto* fr = s2[groups[g].frame].frame;
      if (fr->kind == Step2Kind::kNeutral || fr->triggers.size() <= 1) continue;
      tgroups.push_back({groups[g].frame, angles_of(groups[g].plane)});
      multi_index.push_back(static_cast<int>(g));
    }
    std::vector<Eigen::Vector2d> neutral_angles;
    for (const auto& p : neutral_planes) neutral_angles.push_back(angles_of(p));
    if (!tgroups.empty()) {
      std::string note;
      TriggerModel model;
      const auto slots =
          AssignTriggers(tframes, tgroups, neutral_angles, rec.drive.fast.frequency_hz,
                         rec.drive.slow.frequency_hz, o, &note, &model);
      for (size_t k = 0; k < multi_index.size(); ++k) groups[multi_index[k]].slot = slots[k];
      out.notes.push_back(note);
      // Tentative groups: the one slot their frame's complete groups left free, if the model
      // predicts their angles there within a quarter of the RANSAC inlier threshold (wrong beam
      // pairings are degrees off; the model's RMS is ~0.001 deg on the simulator).
      for (auto& g : recovered) {
        const auto* fr = s2[g.frame].frame;
        std::vector<bool> taken(fr->triggers.size(), false);
        for (const auto& other : groups)
          if (other.frame == g.frame) taken[other.slot] = true;
        const int free_slot =
            static_cast<int>(std::find(taken.begin(), taken.end(), false) - taken.begin());
        if (free_slot >= static_cast<int>(taken.size())) continue;
        const double off_deg = (angles_of(g.plane) - model.Predict(tframes[g.frame].t_s[free_slot],
                                                                   tframes[g.frame].slow_on))
                                   .norm();
        std::ostringstream msg;
        msg << fr->file << ": trigger " << fr->triggers[free_slot] << " (its held-out dot "
            << "missing) from the estimate beams' dots alone, " << off_deg
            << " deg from the drive-phase model: ";
        if (off_deg <= 0.25 * o.ransac_inlier_deg) {
          g.slot = free_slot;
          groups.push_back(g);
          msg << "kept";
        } else {
          msg << "not kept (> " << 0.25 * o.ransac_inlier_deg << " deg)";
        }
        out.notes.push_back(msg.str());
      }
    }
  }
  // Planes: one per (kind, j); neutral frames share one plane.
  std::map<std::pair<int, int>, int> plane_of_key;
  std::vector<std::pair<Step2Kind, int>> plane_keys;
  std::vector<ReflectedDot> validation_dots;
  for (const auto& g : groups) {
    const auto* fr = s2[g.frame].frame;
    const int j = fr->kind == Step2Kind::kNeutral ? -1 : fr->triggers[g.slot];
    const auto key = std::make_pair(static_cast<int>(fr->kind), j);
    auto it = plane_of_key.find(key);
    if (it == plane_of_key.end()) {
      it = plane_of_key.emplace(key, static_cast<int>(plane_keys.size())).first;
      plane_keys.emplace_back(fr->kind, j);
    }
    for (const auto& [b, d] : g.dot_of_beam) {
      const ReflectedDot rd{it->second, b, to_obs(s2[g.frame].dots[d]), s2[g.frame].near_edge[d]};
      (is_estimate[b] ? obs.reflected_dots : validation_dots).push_back(rd);
    }
  }
  obs.num_planes = static_cast<int>(plane_keys.size());
  for (const auto& [kind, j] : plane_keys) {
    if (kind == Step2Kind::kNeutral) ++out.num_neutral_planes;
    if (kind == Step2Kind::kFastOnly) ++out.num_fast_only_planes;
    if (kind == Step2Kind::kScan) ++out.num_scan_planes;
  }
  if (out.num_neutral_planes == 0) throw fail("step2: no usable neutral frame (needed for {0})");
  if (out.num_fast_only_planes < 2)
    throw fail("step2: " + std::to_string(out.num_fast_only_planes) +
               " usable fast_only mirror planes; {0} needs >= 2");

  // ---------------- Estimation ----------------
  {
    int dropped = 0;
    obs.corners = MergeRepeatedViews(obs.corners, corners_clear, &dropped);
    if (dropped > 0)
      out.notes.push_back("corners: " + std::to_string(dropped) +
                          " board corner(s) left out: a laser dot reached their refinement "
                          "window in every frame of their view (or too few corners of the view "
                          "were left)");
  }
  std::string err;
  const auto init = InitialEstimate(obs, &err);
  if (!init) throw fail("initial values: " + err);
  out.mle = SolveMle(obs, *init, o.mle);
  if (!out.mle.usable) throw fail("maximum-likelihood solve failed: " + out.mle.message);
  const Estimate& est = out.mle.estimate;

  // {0}.
  // Origin on the neutral plane, least-squares closest to the scan planes (home_frame.h).
  int neutral_index = -1;
  std::vector<int> fast_index, scan_index;
  for (int p = 0; p < obs.num_planes; ++p) {
    if (plane_keys[p].first == Step2Kind::kNeutral) neutral_index = p;
    if (plane_keys[p].first == Step2Kind::kFastOnly) fast_index.push_back(p);
    if (plane_keys[p].first == Step2Kind::kScan) scan_index.push_back(p);
  }
  auto frame_of = [&](const std::vector<Plane>& planes) {
    std::vector<Plane> fast, scan;
    for (int p : fast_index) fast.push_back(planes[p]);
    for (int p : scan_index) scan.push_back(planes[p]);
    return HomeFrame(planes[neutral_index], geometry::FastAxisFromPlanes(fast), scan);
  };
  out.world_from_mirror0 = frame_of(est.planes);
  {
    std::vector<int> support{neutral_index};
    std::vector<int> fast_sorted = fast_index;
    std::sort(fast_sorted.begin(), fast_sorted.end(),
              [&](int a, int b) { return plane_keys[a].second < plane_keys[b].second; });
    support.insert(support.end(), fast_sorted.begin(), fast_sorted.end());
    for (int p : support)
      out.support_planes.push_back(
          {plane_keys[p].first, plane_keys[p].second, est.planes[p], out.mle.plane_cov[p]});
  }
  const Eigen::Vector3d x_o = out.world_from_mirror0.translation;

  // Uncertainty of {0} itself: its error phi = [rotation vector (3), dX_O (3)] is a function of
  // the neutral, fast-only and scan planes, phi = sum_k W_k dx_k (central differences). With
  // x_k = own_k - G_k^T o (mle.h), Cov(phi) = sum_k W_k H_k^-1 W_k^T + M Sigma_OO M^T,
  // M = -sum_k W_k G_k^T, and Cov(x_j, phi) = H_j^-1 W_j^T + (-G_j^T) Sigma_OO M^T.
  const MleResult& mle = out.mle;
  const int num_other = static_cast<int>(mle.other_cov.rows());
  auto frame_error = [&](const Rigid3d& f) {
    Eigen::Matrix<double, 6, 1> e;
    e.head<3>() =
        geometry::So3Log(f.RotationMatrix() * out.world_from_mirror0.RotationMatrix().transpose());
    e.tail<3>() = f.translation - x_o;
    return e;
  };
  std::vector<Eigen::Matrix<double, 6, 3>> frame_w(obs.num_planes,
                                                   Eigen::Matrix<double, 6, 3>::Zero());
  std::vector<int> frame_set = scan_index;
  frame_set.push_back(neutral_index);
  frame_set.insert(frame_set.end(), fast_index.begin(), fast_index.end());
  std::vector<Plane> perturbed = est.planes;
  auto neg_gt = [&](int p) {  // -G_p^T, 3 x num_other
    return Eigen::MatrixXd(-Eigen::MatrixXd(mle.plane_gain.middleCols(3 * p, 3)).transpose());
  };
  Eigen::Matrix<double, 6, 6> cov_phi = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::MatrixXd m_phi = Eigen::MatrixXd::Zero(6, num_other);
  for (int p : frame_set) {
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d h = Eigen::Vector3d::Zero();
      h(k) = 1e-6;
      perturbed[p] = PlaneFromChart(est.planes[p], h);
      const auto plus = frame_error(frame_of(perturbed));
      perturbed[p] = PlaneFromChart(est.planes[p], -h);
      const auto minus = frame_error(frame_of(perturbed));
      frame_w[p].col(k) = (plus - minus) / 2e-6;
    }
    perturbed[p] = est.planes[p];
    cov_phi += frame_w[p] * mle.plane_own_cov[p] * frame_w[p].transpose();
    m_phi += frame_w[p] * neg_gt(p);
  }
  const Eigen::MatrixXd m_sigma = m_phi * mle.other_cov;  // 6 x num_other
  cov_phi += m_sigma * m_phi.transpose();
  out.mirror0_cov = cov_phi;

  // Rows.
  std::map<int, double> t_of_j;
  for (const auto& t : rec.triggers) t_of_j[t.j] = t.t_s;
  auto pose_vec = [&](const Rigid3d& frame, const Plane& p) {
    const auto pose = geometry::PoseFromWorldPlane(frame, p);
    return Eigen::Vector3d(pose.alpha_rad * kRadToDeg, pose.beta_rad * kRadToDeg, pose.trans_mm);
  };
  std::vector<int> scan_planes = scan_index;
  std::sort(scan_planes.begin(), scan_planes.end(),
            [&](int a, int b) { return plane_keys[a].second < plane_keys[b].second; });
  for (int p : scan_planes) {
    dataset::MirrorPlaneRow row;
    row.j = plane_keys[p].second;
    row.t_s = t_of_j[row.j];
    row.plane_in_world = est.planes[p];
    const Eigen::Vector3d v = pose_vec(out.world_from_mirror0, est.planes[p]);
    row.alpha_deg = v(0);
    row.beta_deg = v(1);
    row.trans_mm = v(2);
    // Pose in {0} as a function of the plane (chart) and of {0}'s error phi.
    Eigen::Matrix3d a;
    Eigen::Matrix<double, 3, 6> f;
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d h = Eigen::Vector3d::Zero();
      h(k) = 1e-6;
      a.col(k) = (pose_vec(out.world_from_mirror0, PlaneFromChart(est.planes[p], h)) -
                  pose_vec(out.world_from_mirror0, PlaneFromChart(est.planes[p], -h))) /
                 2e-6;
    }
    for (int k = 0; k < 6; ++k) {
      Eigen::Matrix<double, 6, 1> e = Eigen::Matrix<double, 6, 1>::Zero();
      auto moved = [&](double h) {
        e(k) = h;
        return Rigid3d(geometry::So3Exp(e.head<3>()) * out.world_from_mirror0.RotationMatrix(),
                       x_o + e.tail<3>());
      };
      f.col(k) =
          (pose_vec(moved(1e-6), est.planes[p]) - pose_vec(moved(-1e-6), est.planes[p])) / 2e-6;
    }
    const Eigen::Matrix<double, 3, 6> cross =
        mle.plane_own_cov[p] * frame_w[p].transpose() + neg_gt(p) * m_sigma.transpose();
    const Eigen::Matrix3d cov = a * mle.plane_cov[p] * a.transpose() + a * cross * f.transpose() +
                                f * cross.transpose() * a.transpose() + f * cov_phi * f.transpose();
    row.sigma_alpha_deg = std::sqrt(std::max(cov(0, 0), 0.0));
    row.sigma_beta_deg = std::sqrt(std::max(cov(1, 1), 0.0));
    row.sigma_trans_mm = std::sqrt(std::max(cov(2, 2), 0.0));
    out.planes.push_back(row);
  }
  for (int b = 0; b < num_beams; ++b) {
    const Line& l = est.beams[b];
    out.beams.push_back({beam_ids[b], l.PointAt(l.Parameter(x_o)), l.v});
  }
  // Spanning angle of the first two estimate beams on the scan planes.
  std::vector<int> est_beams;
  for (int b = 0; b < num_beams; ++b)
    if (is_estimate[b]) est_beams.push_back(b);
  {
    std::map<std::pair<int, int>, Eigen::Vector3d> dot_world;
    for (const auto& r : obs.reflected_dots)
      if (auto x = BackProjectToBoard(rec.camera, est.c2_from_world, r.obs.px))
        dot_world[{r.plane, r.beam}] = *x;
    double sum = 0;
    int cnt = 0;
    for (int p : scan_planes) {
      const auto a = dot_world.find({p, est_beams[0]}), b = dot_world.find({p, est_beams[1]});
      if (a == dot_world.end() || b == dot_world.end()) continue;
      const Line& la = est.beams[est_beams[0]];
      const Line& lb = est.beams[est_beams[1]];
      const Eigen::Vector3d na = la.v.cross(a->second) + la.m, nb = lb.v.cross(b->second) + lb.m;
      double ang = geometry::AngleBetween(na, nb) * kRadToDeg;
      if (ang > 90) ang = 180 - ang;
      sum += ang;
      ++cnt;
    }
    out.mean_spanning_angle_deg = cnt ? sum / cnt : 0;
  }
  // Baseline and validation.
  out.baseline = FitBaseline(est.beams, est_beams, obs.reflected_dots, obs.num_planes, rec.camera,
                             est.c2_from_world);
  double s_deg = 0, s_px = 0, sb_deg = 0, sb_px = 0, s_norm = 0;
  auto angular_error = [&](const Line& beam, const Plane& mirror, const Eigen::Vector2d& obs_px,
                           const Eigen::Vector2d& pred_px) {
    const auto h = geometry::IntersectLinePlane(beam, mirror);
    const auto xo = BackProjectToBoard(rec.camera, est.c2_from_world, obs_px);
    const auto xp = BackProjectToBoard(rec.camera, est.c2_from_world, pred_px);
    if (!h || !xo || !xp) return 0.0;
    return geometry::AngleBetween(*xo - *h, *xp - *h) * kRadToDeg;
  };
  for (const auto& vd : validation_dots) {
    if (plane_keys[vd.plane].first != Step2Kind::kScan) continue;
    const Plane& mirror = est.planes[vd.plane];
    const Line& beam = est.beams[vd.beam];
    const auto pred = PredictReflectedDot(rec.camera, est.c2_from_world, beam, mirror);
    const auto pred_b =
        PredictReflectedDot(rec.camera, est.c2_from_world, beam, out.baseline.planes[vd.plane]);
    if (!pred || !pred_b) continue;
    ValidationDetail d;
    const int j = plane_keys[vd.plane].second;
    d.row = {beam_ids[vd.beam], j, (*pred - vd.obs.px).norm(),
             angular_error(beam, mirror, vd.obs.px, *pred)};
    d.baseline = {beam_ids[vd.beam], j, (*pred_b - vd.obs.px).norm(),
                  angular_error(beam, out.baseline.planes[vd.plane], vd.obs.px, *pred_b)};
    // eq. 10: J Sigma J^T over [plane (3), c2 (6), beam (4)] plus the dot's own covariance.
    const Eigen::MatrixXd joint = out.mle.JointCovariance(vd.plane);
    std::vector<int> idx = {0, 1, 2};
    for (int k = 0; k < 6; ++k) idx.push_back(3 + out.mle.OffsetC2() + k);
    for (int k = 0; k < 4; ++k) idx.push_back(3 + out.mle.OffsetBeam(vd.beam) + k);
    Eigen::MatrixXd jac(2, 13);
    for (int k = 0; k < 13; ++k) {
      auto eval = [&](double h) {
        Eigen::Vector3d xp = Eigen::Vector3d::Zero();
        Eigen::Matrix<double, 6, 1> xt = Eigen::Matrix<double, 6, 1>::Zero();
        Eigen::Vector4d xb = Eigen::Vector4d::Zero();
        if (k < 3)
          xp(k) = h;
        else if (k < 9)
          xt(k - 3) = h;
        else
          xb(k - 9) = h;
        return PredictReflectedDot(rec.camera, TransformFromChart(est.c2_from_world, xt),
                                   BeamFromChart(beam, xb), PlaneFromChart(mirror, xp))
            .value_or(*pred);
      };
      jac.col(k) = (eval(1e-6) - eval(-1e-6)) / 2e-6;
    }
    Eigen::MatrixXd sub(13, 13);
    for (int a = 0; a < 13; ++a)
      for (int b = 0; b < 13; ++b) sub(a, b) = joint(idx[a], idx[b]);
    // The held-out dot's own covariance with the reflected-dot variance factor of the MLE.
    const Eigen::Matrix2d c =
        jac * sub * jac.transpose() +
        vd.obs.cov_px2 *
            out.mle.covariance_scale[vd.near_board_edge ? kReflectedDotsNearEdge : kReflectedDots];
    const Eigen::Vector2d e = vd.obs.px - *pred;
    d.predicted_sigma_px = std::sqrt(c.trace() / 2);
    d.normalised_error = std::sqrt(e.dot(c.ldlt().solve(e)) / 2);
    s_deg += d.row.err_deg * d.row.err_deg;
    s_px += d.row.err_px * d.row.err_px;
    sb_deg += d.baseline.err_deg * d.baseline.err_deg;
    sb_px += d.baseline.err_px * d.baseline.err_px;
    s_norm += d.normalised_error * d.normalised_error;
    out.validation.push_back(d);
  }
  std::sort(out.validation.begin(), out.validation.end(), [](const auto& a, const auto& b) {
    return std::make_pair(a.row.beam, a.row.j) < std::make_pair(b.row.beam, b.row.j);
  });
  if (const double n = static_cast<double>(out.validation.size()); n > 0) {
    out.rms_validation_deg = std::sqrt(s_deg / n);
    out.rms_validation_px = std::sqrt(s_px / n);
    out.rms_baseline_deg = std::sqrt(sb_deg / n);
    out.rms_baseline_px = std::sqrt(sb_px / n);
    out.rms_normalised_validation = std::sqrt(s_norm / n);
  }
  finish_detections(&out);
  return out;
}

}  // namespace msmcal::solver

#include "processing/solver/stages/measure.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <functional>
#include <limits>
#include <map>
#include <opencv2/core/utility.hpp>
#include <optional>
#include <sstream>
#include <thread>

namespace msmcal::solver {
namespace {

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

// `expected[i]`: the dots image i should show (0: not checked). An image whose first pass finds
// fewer on its board's plane is measured again with settings from its own data
// (AdaptiveDotOptions); the second pass is kept if it finds more.
// `view[i]`: the camera view of image i (PipelineOptions::hint_boards_from_first_frame): each
// view's images take their hints as ViewHints says; the views' rounds run side by side. The
// rounds do not depend on `image_threads`, so neither do the measurements.
std::vector<ImageMeasurement> MeasureImages(
    const std::vector<std::string>& files,
    const std::vector<std::vector<vision::BoardSize>>& boards, const ImageLoader& load,
    const PipelineOptions& o, const std::vector<int>& expected, const std::vector<int>& view) {
  std::vector<ImageMeasurement> out(files.size());
  auto measure = [&](size_t i, const BoardHints* hints) {
    const cv::Mat img = load(files[i]);
    if (img.empty()) throw SolveError(files[i] + ": cannot read the image");
    out[i] = MeasureFrame(img, boards[i], expected[i], o, hints);
  };
  if (!o.hint_boards_from_first_frame) {
    ForEachImage(files.size(), o.image_threads, [&](size_t i) { measure(i, nullptr); });
    return out;
  }
  struct View {
    std::vector<size_t> images;  // file order
    std::optional<ViewHints> hints;
  };
  std::map<int, View> views;
  for (size_t i = 0; i < files.size(); ++i) views[view[i]].images.push_back(i);
  // Hints only transfer between images that ask for the same boards.
  for (auto& [id, v] : views) {
    for (size_t i : v.images)
      if (boards[i].size() != boards[v.images[0]].size())
        throw std::invalid_argument("MeasureImages: the images of a view ask for different boards");
    v.hints.emplace(boards[v.images[0]].size(), v.images.size());
  }
  // The hints change only between rounds (Add), never while a round is measured.
  for (;;) {
    std::vector<std::pair<View*, size_t>> batch;  // (view, position in it)
    for (auto& [id, v] : views) {
      const auto [begin, end] = v.hints->NextRound();
      for (size_t k = begin; k < end; ++k) batch.emplace_back(&v, k);
    }
    if (batch.empty()) break;
    ForEachImage(batch.size(), o.image_threads, [&](size_t k) {
      const auto& [v, position] = batch[k];
      measure(v->images[position], &v->hints->hints());
    });
    for (const auto& [v, position] : batch)
      v->hints->Add(position, out[v->images[position]], o.boards);
  }
  std::vector<std::pair<size_t, const BoardHints*>> rest;
  for (const auto& [id, v] : views)
    for (size_t k = v.hints->next(); k < v.images.size(); ++k)
      rest.emplace_back(v.images[k], &v.hints->hints());
  ForEachImage(rest.size(), o.image_threads,
               [&](size_t k) { measure(rest[k].first, rest[k].second); });
  return out;
}

// Blobs that are the scene's own structure, not laser light (the top-hat's residue of board
// squares, of the plate's corners and edges): a blob found at the same place, within
// `radius_px`, in images of one static group whose light (`light[i]`: step 1 the unblocked
// beams, step 2 the (beam, trigger) pairs; sorted) has nothing in common cannot be any of their
// spots. In step 2 (`every_view[g]`) it must be in every image of the group: the mirror takes
// one orientation at several pattern times (the Lissajous figure's crossings; a fast-only
// pattern passes through neutral), so two triggers' dots can coincide. Dropped from every
// image of the group that shows it; the count goes to dot_rejections.static_blob and
// dots_on_plane is recounted.
void DropStaticBlobs(const std::vector<std::vector<size_t>>& groups,
                     const std::vector<std::vector<vision::BoardSize>>& sizes,
                     const std::vector<std::vector<int>>& light,
                     const std::vector<char>& every_view, const PipelineOptions& o,
                     std::vector<ImageMeasurement>* measured) {
  if (o.static_blob_radius_px <= 0) return;
  const double r2 = o.static_blob_radius_px * o.static_blob_radius_px;
  for (size_t g = 0; g < groups.size(); ++g) {
    const auto& group = groups[g];
    if (group.size() < (every_view[g] ? 3u : 2u)) continue;
    std::map<size_t, std::vector<char>> drop;
    for (size_t i : group) {
      const auto& dots = (*measured)[i].dots;
      std::vector<char>& mine = drop[i];
      mine.assign(dots.size(), 0);
      for (size_t k = 0; k < dots.size(); ++k) {
        std::vector<int> common = light[i];
        bool seen_elsewhere = false, in_every_view = true;
        for (size_t j : group) {
          if (j == i) continue;
          const auto& other = (*measured)[j].dots;
          if (std::none_of(other.begin(), other.end(), [&](const vision::Dot& e) {
                return (e.px - dots[k].px).squaredNorm() <= r2;
              })) {
            in_every_view = false;
            continue;
          }
          seen_elsewhere = true;
          std::vector<int> both;
          std::set_intersection(common.begin(), common.end(), light[j].begin(), light[j].end(),
                                std::back_inserter(both));
          common.swap(both);
        }
        mine[k] = seen_elsewhere && common.empty() && (in_every_view || !every_view[g]);
      }
    }
    for (size_t i : group) {
      ImageMeasurement& m = (*measured)[i];
      const std::vector<char>& mine = drop.at(i);
      const int n = static_cast<int>(std::count(mine.begin(), mine.end(), 1));
      if (n == 0) continue;
      std::vector<vision::Dot> kept;
      for (size_t k = 0; k < m.dots.size(); ++k)
        if (!mine[k]) kept.push_back(m.dots[k]);
      m.dots = std::move(kept);
      m.dot_rejections.static_blob += n;
      const bool has_host =
          sizes[i].size() == 2 ? m.boards[1].has_value() : m.boards[0].has_value();
      if (has_host) {
        RegionRejections region;
        m.dots_on_plane = DotsOnHostPlane(m.dots, m, sizes[i], o, &region).size();
      }
    }
  }
}

// The third dot pass (PipelineOptions::background_dots): every frame of a static group whose
// dots on its board's plane fall short of `expected` (step 1: differ from it) is measured on
// its difference from the
// group without it (per pixel the smallest value over the other images; where the frame holds
// the group's smallest, the second smallest). Images are read again, each once per group
// with a short frame; the short frames are then measured `threads` at a time.
void DotsOverStaticBackground(const std::vector<std::vector<size_t>>& groups,
                              const std::vector<std::string>& files,
                              const std::vector<std::vector<vision::BoardSize>>& sizes,
                              const std::vector<int>& expected,
                              const std::vector<std::vector<int>>& step1_beams,
                              const ImageLoader& load, const PipelineOptions& o,
                              std::vector<ImageMeasurement>* measured) {
  auto host_of = [&](size_t i) -> const std::optional<vision::CheckerboardDetection>& {
    const auto& m = (*measured)[i];
    return sizes[i].size() == 2 ? m.boards[1] : m.boards[0];
  };
  // How far a count is from what the frame shows (one dot per listed beam and trigger). A
  // shortfall or a surplus (residue or texture taken for a spot: the data-driven second pass
  // on dim small spots finds board texture too) is measured again, and the difference is kept
  // only if it brings the count closer. A step 1 frame is measured this way only if each of its
  // beams is blocked in another image of its pose (else the difference removes its spot).
  auto off_count = [&](size_t i, size_t n) {
    const size_t want = static_cast<size_t>(expected[i]);
    return n > want ? n - want : want - n;
  };
  auto needs_pass = [&](size_t i, size_t n) { return n != static_cast<size_t>(expected[i]); };
  for (const auto& group : groups) {
    if (group.size() < 2) continue;
    // A frame of the group that shows no dot (every beam blocked) but has blobs on its board's
    // plane says the passes on the image take texture for spots here (dim spots in noise on
    // small squares): a count that matches may then hold texture instead of a spot, and every
    // frame of the group is measured on its difference too, kept where it comes at least as
    // close to the expected count.
    const bool texture_as_dots = std::any_of(group.begin(), group.end(), [&](size_t i) {
      return host_of(i) && expected[i] == 0 && (*measured)[i].dots_on_plane > 0;
    });
    // A frame whose count the second pass (a low threshold over a wide top-hat) completed is
    // measured on its difference too, kept where it comes at least as close: a spot on a
    // square's corner merges with the corner's residue there and its centre moves (a
    // reflected dot 2 mm from a world-board corner came out 3 px off and its frame could not
    // be grouped); on the difference the corner is gone.
    auto second_pass_made = [&](size_t i) { return (*measured)[i].adaptive_dots; };
    std::vector<size_t> short_frames;
    for (size_t i : group) {
      if (!host_of(i) || expected[i] <= 0 ||
          !(texture_as_dots || second_pass_made(i) || needs_pass(i, (*measured)[i].dots_on_plane)))
        continue;
      bool dot_free_views = true;
      if (i < step1_beams.size())
        for (int b : step1_beams[i])
          dot_free_views =
              dot_free_views && std::any_of(group.begin(), group.end(), [&](size_t j) {
                return j != i && std::find(step1_beams[j].begin(), step1_beams[j].end(), b) ==
                                     step1_beams[j].end();
              });
      if (dot_free_views) short_frames.push_back(i);
    }
    if (short_frames.empty()) continue;
    // One read per image: the short frames' own images are kept for their pass.
    vision::StaticBackground scene;
    std::map<size_t, cv::Mat> own;
    bool same = true;
    for (size_t i : group) {
      const cv::Mat img = load(files[i]);
      if (img.empty()) throw SolveError(files[i] + ": cannot read the image");
      same = same && scene.Add(img);
      if (std::find(short_frames.begin(), short_frames.end(), i) != short_frames.end())
        own[i] = img;
    }
    if (!same) continue;
    ForEachImage(short_frames.size(), o.image_threads, [&](size_t k) {
      const size_t i = short_frames[k];
      const cv::Mat& img = own.at(i);
      ImageMeasurement& m = (*measured)[i];
      vision::DotOptions opts;
      vision::DotRejections rej;
      std::vector<vision::Dot> dots = vision::DetectDotsOverBackgroundAdaptive(
          img, scene.Without(img), host_of(i)->square_px, o.dots, &opts, &rej);
      RegionRejections region;
      const size_t found = DotsOnHostPlane(dots, m, sizes[i], o, &region).size();
      const size_t before = off_count(i, m.dots_on_plane), after = off_count(i, found);
      if (after > before || (after == before && !texture_as_dots && !m.adaptive_dots) ||
          found > static_cast<size_t>(expected[i] + o.max_surplus_dots))
        return;
      std::ostringstream what;
      what << "dots on the frame's difference from its static scene (" << group.size() - 1
           << " other images): threshold " << opts.threshold_fraction << " of full scale, min "
           << opts.min_pixels << " px (" << m.dots_on_plane << " -> " << found << " on the plane)";
      m.dots = std::move(dots);
      m.dot_rejections = rej;
      m.adaptive_dots = true;
      m.dot_settings = what.str();
      m.dots_on_plane = found;
    });
  }
}

// Refits every dot over a background measured in the other images of its static group (same
// camera and board placement: all of step 2; step 1 image by sliding pose), where its pixels
// are dot-free (vision/dots.h). The images are read a second time, `threads` at a time; the
// background sums are added in image order, so the result does not depend on the scheduling.
// Dots without a dot-free view of every window pixel keep their first measurement.
void RefineDotsOnBackgrounds(const std::vector<std::vector<size_t>>& groups,
                             const std::vector<std::string>& camera_of_group,
                             const std::vector<std::string>& files, const ImageLoader& load,
                             const vision::DotOptions& dot_options, int threads,
                             std::vector<ImageMeasurement>* measured,
                             std::vector<std::string>* notes) {
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
    const int interpolated =
        dot_options.native_green_only ? vision::InterpolatedGreenParity(img) : -1;
    for (const auto& d : (*measured)[i].dots)
      own[i].push_back(vision::ReadDotSignal(img, vision::DotFitWindow(d, img.size(), dot_options),
                                             interpolated));
  });
  // Each window's background (kept for the non-linear case) and its plain fit; each camera's
  // fitted gammas (the curved fit tried on every dot, kept nowhere yet).
  struct Refit {
    vision::BackgroundPatch background;
    std::optional<vision::Dot> plain;  // empty: no dot-free view of the window, or no fit
  };
  std::vector<std::vector<Refit>> refits(groups.size());
  std::map<std::string, std::vector<double>> gammas;
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
    refits[g].resize(windows[g].size());
    for (size_t w = 0; w < windows[g].size(); ++w) {
      Refit& r = refits[g][w];
      for (size_t i : groups[g])
        if (!contribution[i].empty()) r.background.Add(contribution[i][w]);
      const Window& win = windows[g][w];
      vision::Dot plain = (*measured)[win.image].dots[win.dot];
      vision::ResponseTrial trial;
      if (vision::RefineDotOnBackground(own[win.image][win.dot], r.background, dot_options, &plain,
                                        /*allow_curved=*/false, &trial))
        r.plain = plain;
      if (trial.converged) gammas[camera_of_group[g]].push_back(trial.gamma);
    }
  }
  // One response per camera: linear where the median of its dots' fitted gammas is within
  // vision::kMinResponseBend of 1 (every dot keeps the plain fit; a single dot's gamma can come
  // out 0.2-0.8 from noise), else each dot may take the curved fit where its own data say so
  // (as RefineDotOnBackground decides alone, also for a camera with too few dots to tell).
  constexpr size_t kMinPool = 5;
  std::map<std::string, bool> linear;
  for (auto& [camera, pool] : gammas) {
    if (pool.size() < kMinPool) continue;
    std::nth_element(pool.begin(), pool.begin() + pool.size() / 2, pool.end());
    const double median = pool[pool.size() / 2];
    linear[camera] = std::abs(median - 1) <= vision::kMinResponseBend;
    std::ostringstream note;
    note << "camera response (" << camera << "): median fitted gamma " << median << " over "
         << pool.size() << " dots: "
         << (linear[camera] ? "linear, every dot fitted without a response curve"
                            : "not linear, each dot fitted through a response curve where its "
                              "own pixels say so");
    notes->push_back(note.str());
  }
  for (size_t g = 0; g < groups.size(); ++g) {
    const auto it = linear.find(camera_of_group[g]);
    const bool is_linear = it != linear.end() && it->second;
    for (size_t w = 0; w < refits[g].size(); ++w) {
      const Window& win = windows[g][w];
      vision::Dot* dot = &(*measured)[win.image].dots[win.dot];
      if (is_linear) {
        if (refits[g][w].plain) *dot = *refits[g][w].plain;
      } else {
        vision::RefineDotOnBackground(own[win.image][win.dot], refits[g][w].background, dot_options,
                                      dot);
      }
    }
  }
}

}  // namespace

// Step 1: the plate does not move within a sliding pose, so a frame of a pose whose sliding
// board was not found (a laser spot on a square corner can break the detectors' grid) takes the
// board of the pose's first frame that shows it, before the dot passes: its dots are then read
// on the plate and refitted over the pose's other images like any other frame's. The borrowed
// corners are not measurements of this image (board_from; MeasureStep1Frames fits them once).
void BorrowSlidingBoards(const std::vector<std::vector<size_t>>& step1_groups,
                         const std::vector<std::vector<vision::BoardSize>>& sizes,
                         const PipelineOptions& o, std::vector<ImageMeasurement>* measured) {
  for (const auto& group : step1_groups) {
    const auto source = std::find_if(group.begin(), group.end(), [&](size_t i) {
      return (*measured)[i].boards.size() == 2 && (*measured)[i].boards[1].has_value();
    });
    if (source == group.end()) continue;
    for (size_t i : group) {
      ImageMeasurement& m = (*measured)[i];
      if (m.boards.size() != 2 || m.boards[1]) continue;
      // A frame without the contrast a board needs (black, blank, saturated) shows no plate.
      if (m.board_attempts.size() == 2 &&
          std::any_of(m.board_attempts[1].begin(), m.board_attempts[1].end(),
                      [](const vision::BoardAttempt& a) {
                        return a.method == vision::BoardMethod::kContrastCheck;
                      }))
        continue;
      m.boards[1] = (*measured)[*source].boards[1];
      m.board_from.assign(2, -1);
      m.board_from[1] = static_cast<int>(*source);
      RegionRejections region;
      m.dots_on_plane = DotsOnHostPlane(m.dots, m, sizes[i], o, &region).size();
    }
  }
}

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
  const vision::BoardArea area(board, size);
  const cv::Matx33d h = BoardHomographyOrIdentity(board, size);
  const double junction_px = o.junction_exclusion_squares * board.square_px;
  std::vector<vision::Dot> out;
  for (const auto& d : dots) {
    // The host board's own printed area wins over the other board's outline (the sliding plate
    // may hide part of the world board in the image).
    if (!area.Contains(d.px, margin_squares) ||
        (!exclude.empty() && vision::InsideOutline(exclude, d.px) && !area.Contains(d.px, 0.5))) {
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

// The corners of `board` that no laser dot of the frame disturbs (their average over a view
// leaves the others out).
std::vector<char> CornersClearOfDots(const vision::CheckerboardDetection& board,
                                     const std::vector<vision::Dot>& dots) {
  std::vector<cv::Rect> boxes;
  for (const auto& d : dots) boxes.push_back(d.blob_box);
  return vision::CornersClearOfSpots(board, boxes);
}

BoardHints HintsFrom(const ImageMeasurement& m, const vision::CheckerboardOptions& options) {
  BoardHints hints;
  for (const auto& b : m.boards)
    hints.push_back(b ? std::optional(vision::HintFrom(*b, m.image_size, options)) : std::nullopt);
  // Board 0 is the world board (MeasureFrame's `boards`): fixed before the camera of its view.
  if (!hints.empty() && hints[0]) hints[0]->fixed = true;
  return hints;
}

ViewHints::ViewHints(size_t boards, size_t images)
    : images_(images), hints_(boards), source_(boards, -1) {}

bool ViewHints::Complete() const {
  return std::all_of(hints_.begin(), hints_.end(), [](const auto& h) { return h.has_value(); });
}

std::pair<size_t, size_t> ViewHints::NextRound() {
  if (Complete() || next_ == images_) return {next_, next_};
  const size_t begin = next_;
  next_ = std::min(images_, 2 * begin + 1);  // 1, then 2, 4, 8, ... images
  return {begin, next_};
}

void ViewHints::Add(size_t position, const ImageMeasurement& m,
                    const vision::CheckerboardOptions& options) {
  if (m.boards.size() != hints_.size())
    throw std::invalid_argument("ViewHints::Add: the image asked for other boards");
  const BoardHints found = HintsFrom(m, options);
  for (size_t b = 0; b < found.size(); ++b) {
    if (!found[b] || hints_[b]) continue;
    hints_[b] = found[b];
    source_[b] = static_cast<int>(position);
  }
}

ImageMeasurement MeasureImage(const cv::Mat& img, const std::vector<vision::BoardSize>& boards,
                              const vision::DotOptions& dot_options,
                              const vision::CheckerboardOptions& board_options,
                              const BoardHints* hints) {
  if (hints && hints->size() != boards.size())
    throw std::invalid_argument("MeasureImage: one hint (or none) per board asked for");
  // OpenCV's detectors draw from the calling thread's cv::theRNG(): reseed it per image so
  // that an image's measurement does not depend on which images its thread measured before.
  cv::theRNG() = cv::RNG(0x6d736d63616cULL);
  ImageMeasurement m;
  m.image_size = img.size();
  m.channels = img.channels();
  m.depth_bits = img.depth() == CV_16U ? 16 : 8;
  if (boards.size() == 1) {
    m.board_attempts.resize(1);
    const vision::BoardHint* hint = hints && (*hints)[0] ? &*(*hints)[0] : nullptr;
    m.boards = {vision::DetectCheckerboard(img, boards[0], board_options, cv::Mat(),
                                           &m.board_attempts[0], hint)};
  } else {
    m.boards = vision::DetectCheckerboards(img, boards, board_options, &m.board_attempts, hints);
  }
  m.dots = vision::DetectDots(img, dot_options, &m.dot_rejections);
  return m;
}

ImageMeasurement MeasureFrame(const cv::Mat& img, const std::vector<vision::BoardSize>& sizes,
                              int expected, const PipelineOptions& o, const BoardHints* hints) {
  ImageMeasurement m = MeasureImage(img, sizes, o.dots, o.boards, hints);
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

PipelineOptions ResolveDotMargins(const std::vector<std::vector<vision::BoardSize>>& sizes,
                                  const std::vector<int>& expected, const PipelineOptions& o,
                                  std::vector<ImageMeasurement>* measured,
                                  std::vector<std::string>* notes) {
  PipelineOptions out = o;
  if (!o.dot_margin_from_data) return out;
  constexpr double kWholePlane = std::numeric_limits<double>::infinity();
  PipelineOptions whole = o;
  whole.step1_dot_margin_squares = whole.step2_dot_margin_squares = kWholePlane;
  for (const size_t boards : {size_t{2}, size_t{1}}) {
    const bool step1 = boards == 2;
    std::vector<size_t> frames;
    for (size_t i = 0; i < measured->size(); ++i) {
      const ImageMeasurement& m = (*measured)[i];
      if (sizes[i].size() == boards && (step1 ? m.boards[1] : m.boards[0])) frames.push_back(i);
    }
    int within = 0, on_plane = 0;
    for (size_t i : frames) {
      const ImageMeasurement& m = (*measured)[i];
      RegionRejections r;
      const auto want = static_cast<size_t>(std::max(expected[i], 0));
      within += m.dots_on_plane == want;  // counted within the margin by the first pass
      on_plane += DotsOnHostPlane(m.dots, m, sizes[i], whole, &r).size() == want;
    }
    if (on_plane <= within) continue;
    (step1 ? out.step1_dot_margin_squares : out.step2_dot_margin_squares) = kWholePlane;
    for (size_t i : frames) {
      ImageMeasurement& m = (*measured)[i];
      RegionRejections r;
      m.dots_on_plane = DotsOnHostPlane(m.dots, m, sizes[i], out, &r).size();
    }
    std::ostringstream note;
    note << (step1 ? "step 1" : "step 2") << ": the listed dots lie beyond "
         << (step1 ? "step1_dot_margin_squares (" : "step2_dot_margin_squares (")
         << (step1 ? o.step1_dot_margin_squares : o.step2_dot_margin_squares) << ") of the "
         << (step1 ? "sliding" : "world") << " board's squares: " << on_plane << " of "
         << frames.size() << " frames show their dots on the board's whole plane, " << within
         << " within the margin; the whole plane is taken (dot_margin_from_data)";
    notes->push_back(note.str());
  }
  return out;
}

RecordingMeasurement MeasureRecording(const dataset::Recording& rec, const ImageLoader& load,
                                      const PipelineOptions& options) {
  using dataset::Step2Kind;
  RecordingMeasurement out;
  PipelineOptions o = options;
  out.step1_dot_margin_squares = o.step1_dot_margin_squares;
  out.step2_dot_margin_squares = o.step2_dot_margin_squares;
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
      // Views: step 1 (camera c1, the world board fixed), step 2 (camera c2).
      std::vector<int> view(rec.step1.size(), 1);
      view.resize(files.size(), 2);
      measured = MeasureImages(files, asks, load, o, expected, view);
      // Static groups: same camera and board placement (step 1 by sliding pose, all of step 2).
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
      // What light each image shows: step 1 its unblocked beams; step 2 its (beam, trigger)
      // pairs, a neutral frame's trigger taken as -1.
      std::vector<std::vector<int>> light;
      for (const auto& f : rec.step1) {
        light.push_back(f.beams);
        std::sort(light.back().begin(), light.back().end());
      }
      for (const auto& f : rec.step2) {
        std::vector<int> l;
        const std::vector<int> neutral{-1};
        for (int b : f.beams)
          for (int j : f.kind == Step2Kind::kNeutral ? neutral : f.triggers)
            l.push_back(b * 1000003 + j + 1);
        std::sort(l.begin(), l.end());
        light.push_back(std::move(l));
      }
      BorrowSlidingBoards(
          std::vector<std::vector<size_t>>(static_groups.begin(), static_groups.end() - 1), asks,
          options, &measured);
      // From here on, the margins the data ask for.
      o = ResolveDotMargins(asks, expected, options, &measured, &out.log.notes);
      std::vector<char> every_view(static_groups.size(), 0);
      every_view.back() = 1;  // step 2
      DropStaticBlobs(static_groups, asks, light, every_view, o, &measured);
      if (o.background_dots) {
        std::vector<std::vector<int>> step1_beams;
        for (const auto& f : rec.step1) step1_beams.push_back(f.beams);
        DotsOverStaticBackground(static_groups, files, asks, expected, step1_beams, load, o,
                                 &measured);
      }
      if (o.dots.centre == vision::DotCentre::kGaussianFit) {
        // Step 1's images (camera position C1) and step 2's (C2: the last group) pool apart.
        std::vector<std::string> camera_of_group(static_groups.size(), "step 1");
        camera_of_group.back() = "step 2";
        RefineDotsOnBackgrounds(static_groups, camera_of_group, files, load, o.dots,
                                o.image_threads, &measured, &out.log.notes);
        int on_background = 0, top_hat = 0, centroid = 0;
        for (const auto& m : measured)
          for (const auto& d : m.dots)
            (d.on_background ? on_background : d.fitted ? top_hat : centroid)++;
        // Every candidate of every frame: texture blobs too, which the labelling and grouping
        // later leave out (they are the usual weighted centroids), so the words say candidates.
        out.log.notes.push_back(
            "dot candidates (blobs kept before the labelling picks the dots): " +
            std::to_string(on_background) + " fitted over a background measured in other images, " +
            std::to_string(top_hat) + " over the top-hat (no dot-free view of their window), " +
            std::to_string(centroid) + " weighted centroids (fit failed)");
      }
    } catch (const SolveError& e) {
      out.log.error = e.what();
      return out;
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
      if (const auto& found = measured[i].boards[b]; found && !measured[i].Borrowed(b)) {
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
    out.detections.push_back(std::move(d));
  }
  out.images = std::move(measured);
  out.step1_dot_margin_squares = o.step1_dot_margin_squares;
  out.step2_dot_margin_squares = o.step2_dot_margin_squares;
  return out;
}

}  // namespace msmcal::solver

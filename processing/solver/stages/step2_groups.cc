#include "processing/solver/stages/step2_groups.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <set>

#include "processing/solver/initialise.h"

namespace msmcal::solver {

using dataset::Step2Kind;
using geometry::Line;
using geometry::Plane;
using geometry::Rigid3d;

Step2Frames MeasureStep2Frames(const dataset::Recording& rec,
                               const std::vector<ImageMeasurement>& measured,
                               std::vector<FrameDetection> det, const PipelineOptions& o) {
  Step2Frames out;
  std::vector<Step2View>& s2 = out.views;
  std::optional<Rigid3d>& c2_from_world = out.c2_from_world;
  auto done = [&] {
    out.detections = std::move(det);
    return std::move(out);
  };
  const auto world_pts = BoardPoints(rec.world_board);
  const vision::BoardSize world_size{rec.world_board.cols, rec.world_board.rows};
  for (const auto& f : rec.step2) {
    FrameDetection& fd = det[rec.step1.size() + (&f - rec.step2.data())];
    const ImageMeasurement& m = measured[rec.step1.size() + (&f - rec.step2.data())];
    const auto& board = m.boards[0];
    const size_t triggers = f.kind == Step2Kind::kNeutral ? 1 : f.triggers.size();
    const size_t expected = triggers * f.beams.size();
    fd.dots_expected = static_cast<int>(expected);
    if (!board) {
      out.log.dropped.push_back(
          {f.file, "world board (" + SizeText(rec.world_board) + ") not found"});
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
      out.log.notes.push_back(f.file + ": " + std::to_string(dots.size()) + " dot-like blobs, " +
                              std::to_string(expected) +
                              " expected; the reflection grouping picks the consistent ones");
      fd.note = std::to_string(dots.size() - expected) + " surplus blob(s) left out by grouping";
    }
    if (dots.size() != expected && !partial && !surplus) {
      out.log.dropped.push_back({f.file, "found " + std::to_string(dots.size()) +
                                             " laser dots, expected " + std::to_string(expected) +
                                             " (" + std::to_string(triggers) + " trigger(s) x " +
                                             std::to_string(f.beams.size()) + " beam(s))"});
      continue;
    }
    out.corners.push_back({BoardView::kC2World, -1, world_pts, board->corners_px});
    out.corners_clear.push_back(CornersClearOfDots(*board, m.dots));
    if (!c2_from_world) c2_from_world = SolvePlanarPnP(rec.camera, world_pts, board->corners_px);
    s2.push_back({f, static_cast<int>(&f - rec.step2.data()), dots, {}, {}, partial});
  }
  if (!c2_from_world) {
    out.log.error = "step2: no usable step 2 image (the world board (" + SizeText(rec.world_board) +
                    ") must be found and the frame's laser dots counted)";
    return done();
  }
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
  return done();
}

ReflectionGroups GroupReflections(const std::vector<Step2View>& s2, const std::vector<Line>& beams0,
                                  const BeamTable& beam_table, const geometry::CameraModel& camera,
                                  const Rigid3d& c2_from_world_value, const PipelineOptions& o) {
  ReflectionGroups out;
  out.partial_note.resize(s2.size());
  const std::optional<Rigid3d> c2_from_world = c2_from_world_value;
  const std::vector<bool>& is_estimate = beam_table.is_estimate;
  std::vector<Group>& groups = out.groups;
  std::vector<Group>& recovered = out.recovered;
  for (size_t fi = 0; fi < s2.size(); ++fi) {
    const Step2View& s = s2[fi];
    std::vector<int> e, v;
    for (int id : s.frame.beams) {
      const std::optional<int> b = beam_table.IndexOf(id);
      if (!b) {
        out.log.error = UnknownBeamError(s.frame.file, id);
        return out;
      }
      (is_estimate[*b] ? e : v).push_back(*b);
    }
    if (e.size() < 2) {
      out.log.dropped.push_back({s.frame.file, "needs >= 2 beams with role estimate"});
      continue;
    }
    const int n = static_cast<int>(s.dots.size());
    const size_t want = s.frame.kind == Step2Kind::kNeutral ? 1 : s.frame.triggers.size();
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
        const auto px = PredictReflectedDot(camera, *c2_from_world, beams0[e[i]], *plane);
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
          const auto px = PredictReflectedDot(camera, *c2_from_world, beams0[b], c.plane);
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
    if (s.partial && s.frame.kind != Step2Kind::kNeutral && accepted.size() + 1 == want &&
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
      out.partial_note[fi] = std::to_string(accepted.size()) + " of " + std::to_string(want) +
                             " trigger(s) kept (" + std::to_string(n) + " of " +
                             std::to_string(want * s.frame.beams.size()) + " dots found)";
      out.log.notes.push_back(s.frame.file + ": " + std::to_string(n) + " of " +
                              std::to_string(want * s.frame.beams.size()) + " laser dots found; " +
                              std::to_string(accepted.size()) + " of " + std::to_string(want) +
                              " trigger(s) grouped and kept");
    } else if (accepted.size() != want) {
      out.log.dropped.push_back(
          {s.frame.file,
           (s.partial ? "found " + std::to_string(n) + " of " +
                            std::to_string(want * s.frame.beams.size()) + " laser dots and "
                      : std::string()) +
               "could group only " + std::to_string(accepted.size()) + " of " +
               std::to_string(want) + " trigger(s) into consistent mirror planes"});
      continue;
    }
    for (auto& g : accepted) groups.push_back(std::move(g));
  }
  return out;
}

}  // namespace msmcal::solver

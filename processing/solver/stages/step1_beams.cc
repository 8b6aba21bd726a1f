#include "processing/solver/stages/step1_beams.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "processing/solver/initialise.h"

namespace msmcal::solver {

using geometry::Line;
using geometry::Plane;
using geometry::Rigid3d;

Step1Frames MeasureStep1Frames(const dataset::Recording& rec,
                               const std::vector<ImageMeasurement>& measured,
                               std::vector<FrameDetection> det, const BeamTable& beam_table,
                               const PipelineOptions& o) {
  Step1Frames out;
  std::vector<Step1View>& s1 = out.views;
  std::vector<CornerSet>& corners = out.corners;
  std::vector<std::vector<char>>& corners_clear = out.corners_clear;
  std::optional<Rigid3d>& c1_from_world = out.c1_from_world;
  auto done = [&] {
    out.detections = std::move(det);
    return std::move(out);
  };
  const auto world_pts = BoardPoints(rec.world_board);
  const auto sliding_pts = BoardPoints(rec.sliding_board);
  const vision::BoardSize world_size{rec.world_board.cols, rec.world_board.rows};
  const vision::BoardSize sliding_size{rec.sliding_board.cols, rec.sliding_board.rows};
  std::set<int> poses_shown;  // session poses whose sliding board some frame shows
  for (size_t i = 0; i < rec.step1.size(); ++i)
    if (measured[i].boards[1]) poses_shown.insert(rec.step1[i].pose);
  size_t next_measured = 0;
  std::map<int, int> pose_remap;
  std::set<int> poses_with_corners;  // poses (renumbered) whose corners are in `corners`
  std::map<int, size_t> lender;      // pose (renumbered) -> the frame a board was borrowed from
  size_t c1_corners = 0;
  for (const auto& f : rec.step1) {
    FrameDetection& fd = det[next_measured];
    const ImageMeasurement& m = measured[next_measured++];
    const auto& boards = m.boards;
    fd.dots_expected = static_cast<int>(f.beams.size());
    if (!boards[1]) {
      out.log.dropped.push_back(
          {f.file, "sliding board (" + SizeText(rec.sliding_board) + ") not found" +
                       (poses_shown.count(f.pose)
                            ? std::string()
                            : " in this or any other frame of pose " + std::to_string(f.pose))});
      continue;
    }
    const bool borrowed = m.Borrowed(1);
    if (borrowed) {
      const std::string& from = rec.step1[static_cast<size_t>(m.board_from[1])].file;
      out.log.notes.push_back(f.file + ": sliding board not found; the plate of " + from +
                              " (same pose " + std::to_string(f.pose) + ")");
      fd.partial = true;
      fd.note = "sliding board not found: the plate of " + from + " (same pose)" +
                (fd.note.empty() ? "" : "; " + fd.note);
    }
    RegionRejections region;
    auto dots = DotsOnHostPlane(m.dots, m, {world_size, sliding_size}, o, &region);
    RecordDots(dots, m.dots, region, &fd);
    if (f.beams.empty() && !dots.empty()) {
      out.log.notes.push_back(f.file + ": background frame (every beam blocked) shows " +
                              std::to_string(dots.size()) + " dot-like blob(s); ignored");
      dots.clear();
    }
    if (dots.size() > f.beams.size()) {
      // Surplus blobs (checkerboard-junction residue, glints): keep the roundest few as
      // candidates; the beams' lines decide which are the laser dots (LabelBeams).
      auto elongation = [](const vision::Dot& d) {
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(d.cov_px2);
        return es.eigenvalues()(1) / std::max(es.eigenvalues()(0), 1e-12);
      };
      std::stable_sort(dots.begin(), dots.end(),
                       [&](const auto& a, const auto& b) { return elongation(a) < elongation(b); });
      const size_t keep = std::min(dots.size(), f.beams.size() + kSurplusStep1Candidates);
      out.log.notes.push_back(f.file + ": " + std::to_string(dots.size()) + " blobs for " +
                              std::to_string(f.beams.size()) + " beam(s); the " +
                              std::to_string(keep) +
                              " roundest are candidates, the beams' lines pick the dots");
      dots.resize(keep);
    }
    if (dots.empty() && !f.beams.empty()) {
      out.log.dropped.push_back({f.file, "found 0 laser dots, expected " +
                                             std::to_string(f.beams.size()) +
                                             " (one per listed beam)"});
      continue;
    }
    if (dots.size() < f.beams.size())
      out.log.notes.push_back(f.file + ": found " + std::to_string(dots.size()) +
                              " laser dots for " + std::to_string(f.beams.size()) +
                              " beams; the beams' lines label those found");
    const auto c1s = SolvePlanarPnP(rec.camera, sliding_pts, boards[1]->corners_px);
    if (!c1s) {
      out.log.dropped.push_back({f.file, "PnP of the sliding board failed"});
      continue;
    }
    if (!borrowed)
      fd.boards[1].corner_rms_px =
          ReprojectionRms(rec.camera, *c1s, sliding_pts, boards[1]->corners_px);
    if (boards[0]) {
      if (auto t = SolvePlanarPnP(rec.camera, world_pts, boards[0]->corners_px))
        fd.boards[0].corner_rms_px =
            ReprojectionRms(rec.camera, *t, world_pts, boards[0]->corners_px);
      corners.push_back({BoardView::kC1World, -1, world_pts, boards[0]->corners_px});
      corners_clear.push_back(CornersClearOfDots(*boards[0], m.dots));
      if (world_pts.size() > c1_corners) {
        if (auto t = SolvePlanarPnP(rec.camera, world_pts, boards[0]->corners_px)) {
          c1_from_world = t;
          c1_corners = world_pts.size();
        }
      }
    } else {
      out.log.notes.push_back(f.file +
                              ": world board not found; frame used for the sliding board only");
      fd.partial = true;
      fd.note = (fd.note.empty() ? "" : fd.note + "; ") +
                "world board not found: used for the sliding board only";
    }
    const int pose = pose_remap.emplace(f.pose, static_cast<int>(pose_remap.size())).first->second;
    if (!borrowed) {
      corners.push_back({BoardView::kC1Sliding, pose, sliding_pts, boards[1]->corners_px});
      corners_clear.push_back(CornersClearOfDots(*boards[1], m.dots));
      poses_with_corners.insert(pose);
    } else {
      lender.emplace(pose, static_cast<size_t>(m.board_from[1]));
    }
    Step1View s;
    s.file = f.file;
    s.pose = pose;
    for (int id : f.beams) {
      const std::optional<int> b = beam_table.IndexOf(id);
      if (!b) {
        out.log.error = UnknownBeamError(f.file, id);
        return done();
      }
      s.beams.push_back(*b);
    }
    s.dots = dots;
    s.c1_from_sliding = *c1s;
    s1.push_back(std::move(s));
  }
  // A borrowed board whose own frame was dropped (no dot in an identification frame): its
  // corners still give the pose, once.
  for (const auto& [pose, i] : lender)
    if (!poses_with_corners.count(pose)) {
      corners.push_back(
          {BoardView::kC1Sliding, pose, sliding_pts, measured[i].boards[1]->corners_px});
      corners_clear.push_back(CornersClearOfDots(*measured[i].boards[1], measured[i].dots));
    }
  if (!c1_from_world) {
    // The world board's pose comes from the frames kept: say which of the two failed.
    const auto shown = std::count_if(measured.begin(), measured.begin() + rec.step1.size(),
                                     [](const ImageMeasurement& m) { return m.boards[0]; });
    out.log.error = shown == 0
                        ? "step1: the world board (" + SizeText(rec.world_board) +
                              ") was not found in any step 1 image"
                        : "step1: no step 1 frame was kept (the world board (" +
                              SizeText(rec.world_board) + ") was found in " +
                              std::to_string(shown) + " of " + std::to_string(rec.step1.size()) +
                              " frames, each dropped for the reason given)";
    return done();
  }
  out.num_poses = static_cast<int>(pose_remap.size());
  const Rigid3d world_from_c1 = c1_from_world->Inverse();
  Eigen::Vector3d& sliding_z = out.sliding_z;
  std::vector<Rigid3d>& world_from_pose = out.world_from_pose;
  world_from_pose.resize(out.num_poses);
  for (auto& s : s1) {
    world_from_pose[s.pose] = world_from_c1 * s.c1_from_sliding;
    sliding_z += world_from_pose[s.pose].rotation * Eigen::Vector3d::UnitZ();
    for (const auto& d : s.dots) {
      const auto p = BackProjectToBoard(rec.camera, s.c1_from_sliding, d.px);
      s.dots_in_world.push_back(p ? world_from_pose[s.pose] * *p : Eigen::Vector3d::Zero());
    }
  }
  return done();
}

BeamLabels LabelBeams(const std::vector<Step1View>& views,
                      const std::vector<Rigid3d>& world_from_pose, const Eigen::Vector3d& sliding_z,
                      const BeamTable& beam_table) {
  BeamLabels out;
  const int num_beams = beam_table.size();
  const std::vector<int>& beam_ids = beam_table.ids;
  auto to_obs = [](const vision::Dot& d) { return PixelObs{d.px, d.cov_px2}; };
  struct S1 : Step1View {
    std::vector<int> label;  // beam index per dot, -1 unknown
  };
  std::vector<S1> s1;
  for (const auto& v : views) {
    S1 s;
    static_cast<Step1View&>(s) = v;
    s.label.assign(v.dots.size(), -1);
    s1.push_back(std::move(s));
  }
  // A beam's line through its labelled dots (>= 2 poses), and a dot's distance from it.
  auto line_distance = [](const Line& l, const Eigen::Vector3d& p) {
    return (p.cross(l.v) - l.m).norm() / l.v.norm();
  };
  // Consensus labelling (>= 3 sliding poses): the beams are the lines that the dots of many
  // poses share. Lines are found among all candidate dots at once (sequential RANSAC: the line
  // through two dots of different poses that the most poses' dots lie on, within
  // kMaxBeamLineResidualMm, one dot per frame), and only then named, by the frames whose
  // listed beams they agree with (an identification frame counts most). A blob taken for a dot,
  // in any frame, identification frames included, cannot then bend a beam or swap two.
  bool consensus_ok = false;
  {
    struct Cand {
      int frame, dot, pose;
      Eigen::Vector3d x;
    };
    std::vector<Cand> cands;
    std::set<int> all_poses;
    for (size_t k = 0; k < s1.size(); ++k) {
      if (s1[k].beams.empty()) continue;
      for (size_t i = 0; i < s1[k].dots.size(); ++i) {
        cands.push_back(
            {static_cast<int>(k), static_cast<int>(i), s1[k].pose, s1[k].dots_in_world[i]});
        all_poses.insert(s1[k].pose);
      }
    }
    std::vector<bool> taken(cands.size(), false);
    struct Found {
      Line line;
      std::vector<int> members;  // into cands
    };
    std::vector<Found> lines;
    // The members of a line: per frame the nearest untaken candidate within the tolerance.
    auto members_of = [&](const Line& l, std::set<int>* poses, double* cost) {
      std::map<int, std::pair<double, int>> best;  // frame -> (distance, cand)
      for (size_t c = 0; c < cands.size(); ++c) {
        if (taken[c]) continue;
        const double d = line_distance(l, cands[c].x);
        if (d > kMaxBeamLineResidualMm) continue;
        auto it = best.find(cands[c].frame);
        if (it == best.end() || d < it->second.first)
          best[cands[c].frame] = {d, static_cast<int>(c)};
      }
      std::vector<int> m;
      *cost = 0;
      poses->clear();
      for (const auto& [frame, dc] : best) {
        m.push_back(dc.second);
        poses->insert(cands[dc.second].pose);
        *cost += dc.first * dc.first;
      }
      return m;
    };
    if (all_poses.size() >= 3) {
      for (int round = 0; round < num_beams; ++round) {
        size_t best_poses = 0, best_members = 0;
        double best_cost = 1e300;
        std::optional<Line> best_line;
        for (size_t p = 0; p < cands.size(); ++p) {
          if (taken[p]) continue;
          for (size_t q = p + 1; q < cands.size(); ++q) {
            if (taken[q] || cands[p].pose == cands[q].pose ||
                (cands[q].x - cands[p].x).norm() < 1e-6)
              continue;
            const Line l = geometry::FitLine({cands[p].x, cands[q].x});
            std::set<int> poses;
            double cost = 0;
            const std::vector<int> m = members_of(l, &poses, &cost);
            if (std::make_tuple(poses.size(), m.size(), -cost) >
                std::make_tuple(best_poses, best_members, -best_cost)) {
              best_poses = poses.size();
              best_members = m.size();
              best_cost = cost;
              best_line = l;
            }
          }
        }
        if (!best_line || best_poses < 3) break;
        // Refit on the members, take them again with the refitted line.
        std::set<int> poses;
        double cost = 0;
        std::vector<int> m = members_of(*best_line, &poses, &cost);
        std::vector<Eigen::Vector3d> xs;
        for (int c : m) xs.push_back(cands[c].x);
        const Line refit = FitBeam(xs, sliding_z);
        std::vector<int> m2 = members_of(refit, &poses, &cost);
        if (poses.size() >= 3) m = std::move(m2);
        for (int c : m) taken[c] = true;
        lines.push_back({refit, std::move(m)});
      }
    }
    if (static_cast<int>(lines.size()) == num_beams) {
      // Name the lines: score(line, beam) = its members whose frame lists the beam, an
      // identification frame (one listed beam) counting kIdWeight; the best injective naming.
      constexpr double kIdWeight = 10;
      std::vector<std::vector<double>> score(lines.size(), std::vector<double>(num_beams, 0));
      double top = 0;
      for (size_t L = 0; L < lines.size(); ++L)
        for (int c : lines[L].members) {
          const auto& beams = s1[cands[c].frame].beams;
          for (int b : beams) {
            score[L][b] += beams.size() == 1 ? kIdWeight : 1;
            top = std::max(top, score[L][b]);
          }
        }
      const std::vector<int> name = BestInjection(
          static_cast<int>(lines.size()), num_beams,
          [&](int L, int b) { return top - score[L][b]; }, top + 1);
      bool named = true;
      for (size_t L = 0; L < lines.size(); ++L)
        named = named && name[L] >= 0 && score[L][name[L]] > 0;
      if (named) {
        consensus_ok = true;
        for (size_t L = 0; L < lines.size(); ++L)
          for (int c : lines[L].members) {
            S1& s = s1[cands[c].frame];
            if (std::find(s.beams.begin(), s.beams.end(), name[L]) != s.beams.end())
              s.label[cands[c].dot] = name[L];
          }
        int labelled = 0, listed = 0;
        for (const auto& s : s1) {
          listed += static_cast<int>(s.beams.size());
          for (int l : s.label) labelled += l >= 0 ? 1 : 0;
        }
        out.log.notes.push_back("step 1: dot-to-beam labels from " + std::to_string(num_beams) +
                                " consensus lines over " + std::to_string(all_poses.size()) +
                                " poses (" + std::to_string(labelled) + " of " +
                                std::to_string(listed) + " listed beams' dots)");
      }
    }
  }
  std::vector<std::vector<Eigen::Vector3d>> beam_points(num_beams);
  std::vector<std::vector<int>> beam_poses(num_beams);
  if (!consensus_ok) {
    // Identification frames: one beam, one dot.
    std::vector<bool> done(s1.size(), false);
    for (size_t k = 0; k < s1.size(); ++k) {
      if (s1[k].beams.size() != 1 || s1[k].dots.size() != 1) continue;
      s1[k].label[0] = s1[k].beams[0];
      beam_points[s1[k].beams[0]].push_back(s1[k].dots_in_world[0]);
      beam_poses[s1[k].beams[0]].push_back(s1[k].pose);
      done[k] = true;
    }
    // Other frames, nearest to already labelled poses first: predict each beam's dot on the
    // frame's sliding plane (line through >= 2 poses, else the labelled point) and take the best
    // assignment of beams to the frame's dots (a frame may hold surplus candidates or miss a dot).
    for (;;) {
      int next = -1;
      double next_dist = 1e300;
      for (size_t k = 0; k < s1.size(); ++k) {
        if (done[k]) continue;
        double dist = 1e300;
        for (int b : s1[k].beams)
          for (size_t q = 0; q < beam_points[b].size(); ++q)
            dist = std::min(dist,
                            (world_from_pose[s1[k].pose].translation - beam_points[b][q]).norm());
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
        out.log.dropped.push_back({s.file,
                                   "cannot tell its beams apart: a listed beam has no "
                                   "identification frame"});
        continue;
      }
      const int nb = static_cast<int>(s.beams.size());
      const int nd = static_cast<int>(s.dots.size());
      std::vector<int> slot;
      if (nb == nd) {
        slot = BestPermutation(
            nb, [&](int i, int d) { return (pred[i] - s.dots_in_world[d]).squaredNorm(); });
      } else {
        // Unequal counts (surplus candidates or a missing dot): the best partial assignment;
        // the consensus lines below correct a wrong pick.
        slot = BestInjection(
            nb, nd, [&](int i, int d) { return (pred[i] - s.dots_in_world[d]).squaredNorm(); },
            std::numeric_limits<double>::infinity());
      }
      for (int i = 0; i < nb; ++i) {
        if (slot[i] < 0) continue;
        s.label[slot[i]] = s.beams[i];
        beam_points[s.beams[i]].push_back(s.dots_in_world[slot[i]]);
        beam_poses[s.beams[i]].push_back(s.pose);
      }
    }
    // Robust relabelling: each beam's line by consensus over its labelled dots (RANSAC over pairs
    // of dots on different poses, inliers within kMaxBeamLineResidualMm), then every frame's
    // dots assigned to its beams against those lines, a dot farther than the tolerance from
    // every listed beam's line left unlabelled. One wrong dot (a blob taken for a laser dot) can
    // no longer pull a line so far that the right dots look wrong.
    {
      std::vector<std::optional<Line>> robust(num_beams);
      for (int b = 0; b < num_beams; ++b) {
        std::vector<Eigen::Vector3d> pts;
        std::vector<int> poses;
        for (const auto& s : s1)
          for (size_t i = 0; i < s.dots.size(); ++i)
            if (s.label[i] == b) {
              pts.push_back(s.dots_in_world[i]);
              poses.push_back(s.pose);
            }
        if (std::set<int>(poses.begin(), poses.end()).size() < 3) continue;  // no consensus
        size_t best_inliers = 0;
        double best_cost = 1e300;
        std::vector<Eigen::Vector3d> best_set;
        for (size_t p = 0; p < pts.size(); ++p)
          for (size_t q = p + 1; q < pts.size(); ++q) {
            if (poses[p] == poses[q] || (pts[q] - pts[p]).norm() < 1e-6) continue;
            const Line l = geometry::FitLine({pts[p], pts[q]});
            std::vector<Eigen::Vector3d> in;
            double cost = 0;
            for (const auto& x : pts) {
              const double d = line_distance(l, x);
              if (d <= kMaxBeamLineResidualMm) {
                in.push_back(x);
                cost += d * d;
              }
            }
            if (in.size() > best_inliers || (in.size() == best_inliers && cost < best_cost)) {
              best_inliers = in.size();
              best_cost = cost;
              best_set = std::move(in);
            }
          }
        if (best_set.size() >= 2) robust[b] = FitBeam(best_set, sliding_z);
      }
      for (auto& s : s1) {
        const int nb = static_cast<int>(s.beams.size());
        const int nd = static_cast<int>(s.dots.size());
        bool all_robust = nb > 0;
        for (int b : s.beams) all_robust = all_robust && robust[b].has_value();
        if (!all_robust) continue;  // keep the propagated labels
        const std::vector<int> slot = BestInjection(
            nb, nd,
            [&](int i, int d) { return line_distance(*robust[s.beams[i]], s.dots_in_world[d]); },
            kMaxBeamLineResidualMm);
        std::vector<int> label(s.dots.size(), -1);
        for (int i = 0; i < nb; ++i)
          if (slot[i] >= 0) label[slot[i]] = s.beams[i];
        if (label != s.label) {
          int labelled = 0;
          for (int l : label) labelled += l >= 0 ? 1 : 0;
          out.log.notes.push_back(
              s.file + ": dot-to-beam labels set by the beams' consensus lines (" +
              std::to_string(labelled) + " of " + std::to_string(nb) + " beams' dots)");
          s.label = std::move(label);
        }
      }
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
    out.log.dropped.push_back({bad.file, why.str()});
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
      if (s.label[i] >= 0) out.sliding_dots.push_back({s.pose, s.label[i], to_obs(s.dots[i])});
  std::vector<Line>& beams0 = out.beams;
  beams0.resize(num_beams);
  for (int b = 0; b < num_beams; ++b) {
    std::set<int> distinct(beam_poses[b].begin(), beam_poses[b].end());
    if (distinct.size() < 2) {
      out.log.error = "step1: beam " + std::to_string(beam_ids[b]) + " has dots on " +
                      std::to_string(distinct.size()) + " sliding pose(s); needs >= 2";
      break;
    }
    beams0[b] = FitBeam(beam_points[b], sliding_z);
  }
  for (const auto& s : s1) out.label.push_back(s.label);
  return out;
}

}  // namespace msmcal::solver

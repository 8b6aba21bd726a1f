#include "processing/solver/stages/step1_beams.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <map>
#include <set>
#include <sstream>

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
  size_t next_measured = 0;
  std::map<int, int> pose_remap;
  size_t c1_corners = 0;
  for (const auto& f : rec.step1) {
    FrameDetection& fd = det[next_measured];
    const ImageMeasurement& m = measured[next_measured++];
    const auto& boards = m.boards;
    fd.dots_expected = static_cast<int>(f.beams.size());
    if (!boards[1]) {
      out.log.dropped.push_back(
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
      out.log.notes.push_back(f.file + ": background frame (every beam blocked) shows " +
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
      out.log.notes.push_back(f.file + ": kept the " + std::to_string(f.beams.size()) +
                              " roundest of " + std::to_string(dots.size()) + " blobs");
      dots.resize(f.beams.size());
    }
    if (dots.size() != f.beams.size()) {
      out.log.dropped.push_back(
          {f.file, "found " + std::to_string(dots.size()) + " laser dots, expected " +
                       std::to_string(f.beams.size()) + " (one per listed beam)"});
      continue;
    }
    const auto c1s = SolvePlanarPnP(rec.camera, sliding_pts, boards[1]->corners_px);
    if (!c1s) {
      out.log.dropped.push_back({f.file, "PnP of the sliding board failed"});
      continue;
    }
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
      fd.note = "world board not found: used for the sliding board only";
    }
    const int pose = pose_remap.emplace(f.pose, static_cast<int>(pose_remap.size())).first->second;
    corners.push_back({BoardView::kC1Sliding, pose, sliding_pts, boards[1]->corners_px});
    corners_clear.push_back(CornersClearOfDots(*boards[1], m.dots));
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
  if (!c1_from_world) {
    out.log.error = "step1: the world board (" + SizeText(rec.world_board) +
                    ") was not found in any step 1 image";
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
      out.log.dropped.push_back({s.file,
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

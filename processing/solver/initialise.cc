#include "processing/solver/initialise.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace msmcal::solver {

using geometry::Line;
using geometry::Plane;
using geometry::Rigid3d;

std::optional<Rigid3d> SolvePlanarPnP(const geometry::CameraModel& camera,
                                      const std::vector<Eigen::Vector3d>& points,
                                      const std::vector<Eigen::Vector2d>& px) {
  if (points.size() < 4 || points.size() != px.size()) return std::nullopt;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (size_t i = 0; i < points.size(); ++i) {
    object.emplace_back(points[i].x(), points[i].y(), points[i].z());
    image.emplace_back(px[i].x(), px[i].y());
  }
  cv::Mat k;
  cv::eigen2cv(camera.K(), k);
  cv::Mat dist(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) dist.at<double>(i) = camera.distortion[i];
  cv::Mat rvec, tvec;
  try {
    if (!cv::solvePnP(object, image, k, dist, rvec, tvec, false, cv::SOLVEPNP_IPPE))
      return std::nullopt;
    cv::solvePnP(object, image, k, dist, rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
  const Eigen::Vector3d w(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
  const Eigen::Vector3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  return Rigid3d(geometry::So3Exp(w), t);
}

Line FitBeam(const std::vector<Eigen::Vector3d>& dots, const Eigen::Vector3d& sliding_z) {
  Line line = geometry::FitLine(dots);
  if (line.v.dot(sliding_z) < 0) line = Line{-line.v, -line.m};
  return line;
}

std::optional<Plane> InitialMirrorPlane(const std::vector<Line>& beams,
                                        const std::vector<Eigen::Vector3d>& dots) {
  if (beams.size() < 2 || beams.size() != dots.size()) return std::nullopt;
  Eigen::MatrixXd nl(beams.size(), 3);
  for (size_t i = 0; i < beams.size(); ++i) {
    // v x (X - p) = v x X - v x p = v x X + m.
    const Eigen::Vector3d n = beams[i].v.cross(dots[i]) + beams[i].m;
    if (n.norm() < 1e-12) return std::nullopt;
    nl.row(i) = n.normalized().transpose();
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(nl, Eigen::ComputeFullV);
  const Eigen::VectorXd sv = svd.singularValues();
  if (sv.size() >= 2 && sv(1) < 1e-6) return std::nullopt;  // parallel light-path planes
  Eigen::Vector3d n = svd.matrixV().col(2);
  Eigen::Vector3d vsum = Eigen::Vector3d::Zero();
  for (const auto& b : beams) vsum += b.v;
  if (n.dot(vsum) > 0) n = -n;
  // v x X' + m = 0 with X' = X - 2 (n.X) n + 2 d n: (2 v x n) d = -(v x (X - 2 (n.X) n) + m).
  double num = 0, den = 0;
  for (size_t i = 0; i < beams.size(); ++i) {
    const Eigen::Vector3d a = 2.0 * beams[i].v.cross(n);
    const Eigen::Vector3d b = -(beams[i].v.cross(dots[i] - 2.0 * n.dot(dots[i]) * n) + beams[i].m);
    num += a.dot(b);
    den += a.dot(a);
  }
  if (den < 1e-18) return std::nullopt;
  return Plane{n, num / den};
}

Eigen::Vector3d ClosestPointToLines(const std::vector<Line>& lines) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const auto& l : lines) {
    const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - l.v * l.v.transpose();
    a += p;
    b += p * l.ClosestPointToOrigin();
  }
  return a.ldlt().solve(b);
}

std::optional<Estimate> InitialEstimate(const Observations& obs, std::string* error) {
  auto fail = [&](const std::string& what) -> std::optional<Estimate> {
    if (error) *error = what;
    return std::nullopt;
  };
  Estimate est;
  est.c1_from_sliding.resize(obs.num_poses);
  std::vector<bool> have_pose(obs.num_poses, false);
  size_t best_c1 = 0, best_c2 = 0;
  std::vector<size_t> best_s(obs.num_poses, 0);
  for (const auto& cs : obs.corners) {
    const size_t n = cs.px.size();
    size_t* best = cs.view == BoardView::kC1World   ? &best_c1
                   : cs.view == BoardView::kC2World ? &best_c2
                                                    : &best_s[cs.pose];
    if (n <= *best) continue;
    const auto pose = SolvePlanarPnP(obs.camera, cs.points_in_board, cs.px);
    if (!pose) continue;
    *best = n;
    if (cs.view == BoardView::kC1World) est.c1_from_world = *pose;
    if (cs.view == BoardView::kC2World) est.c2_from_world = *pose;
    if (cs.view == BoardView::kC1Sliding) {
      est.c1_from_sliding[cs.pose] = *pose;
      have_pose[cs.pose] = true;
    }
  }
  if (best_c1 == 0) return fail("no step 1 image with a usable world board");
  if (best_c2 == 0) return fail("no step 2 image with a usable world board");
  // Beams from the sliding dots.
  std::vector<std::vector<Eigen::Vector3d>> beam_points(obs.num_beams);
  Eigen::Vector3d sliding_z = Eigen::Vector3d::Zero();
  const Rigid3d world_from_c1 = est.c1_from_world.Inverse();
  for (int l = 0; l < obs.num_poses; ++l)
    if (have_pose[l])
      sliding_z += (world_from_c1 * est.c1_from_sliding[l]).rotation * Eigen::Vector3d::UnitZ();
  for (const auto& d : obs.sliding_dots) {
    if (!have_pose[d.pose]) continue;
    const auto p = BackProjectToBoard(obs.camera, est.c1_from_sliding[d.pose], d.obs.px);
    if (!p) continue;
    beam_points[d.beam].push_back(world_from_c1 * (est.c1_from_sliding[d.pose] * *p));
  }
  est.beams.resize(obs.num_beams);
  for (int b = 0; b < obs.num_beams; ++b) {
    if (beam_points[b].size() < 2)
      return fail("beam index " + std::to_string(b) + " has " +
                  std::to_string(beam_points[b].size()) +
                  " sliding-plane dot(s) on usable poses; needs >= 2");
    est.beams[b] = FitBeam(beam_points[b], sliding_z);
  }
  // Planes from the reflected dots.
  std::vector<std::vector<Line>> plane_beams(obs.num_planes);
  std::vector<std::vector<Eigen::Vector3d>> plane_dots(obs.num_planes);
  for (const auto& r : obs.reflected_dots) {
    const auto x = BackProjectToBoard(obs.camera, est.c2_from_world, r.obs.px);
    if (!x) continue;
    plane_beams[r.plane].push_back(est.beams[r.beam]);
    plane_dots[r.plane].push_back(*x);
  }
  est.planes.resize(obs.num_planes);
  for (int j = 0; j < obs.num_planes; ++j) {
    const auto plane = InitialMirrorPlane(plane_beams[j], plane_dots[j]);
    if (!plane)
      return fail("mirror plane index " + std::to_string(j) + " has " +
                  std::to_string(plane_dots[j].size()) +
                  " reflected dot(s) or parallel light-path planes; needs >= 2 beams");
    est.planes[j] = *plane;
  }
  return est;
}

BaselineModel FitBaseline(const std::vector<Line>& beams, const std::vector<int>& estimate_beams,
                          const std::vector<ReflectedDot>& reflected, int num_planes,
                          const geometry::CameraModel& camera, const Rigid3d& c2_from_world) {
  BaselineModel model;
  std::vector<Line> lines;
  for (int b : estimate_beams) lines.push_back(beams[b]);
  model.centre_in_world = ClosestPointToLines(lines);
  std::vector<Eigen::Vector3d> sum(num_planes, Eigen::Vector3d::Zero());
  for (const auto& r : reflected) {
    if (std::find(estimate_beams.begin(), estimate_beams.end(), r.beam) == estimate_beams.end())
      continue;
    const auto x = BackProjectToBoard(camera, c2_from_world, r.obs.px);
    if (!x) continue;
    const Eigen::Vector3d out = (*x - model.centre_in_world).normalized();
    sum[r.plane] += (out - beams[r.beam].v).normalized();
  }
  model.planes.resize(num_planes);
  for (int j = 0; j < num_planes; ++j) {
    if (sum[j].norm() < 1e-12) continue;
    const Eigen::Vector3d n = sum[j].normalized();
    model.planes[j] = Plane{n, n.dot(model.centre_in_world)};
  }
  return model;
}

}  // namespace msmcal::solver

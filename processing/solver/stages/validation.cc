#include "processing/solver/stages/validation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "common/units.h"
#include "processing/solver/numeric_diff.h"
#include "processing/solver/stages/common.h"

namespace msmcal::solver {

using dataset::Step2Kind;
using geometry::Line;
using geometry::Plane;

std::vector<dataset::BeamRow> BeamRows(const std::vector<Line>& beams,
                                       const std::vector<int>& beam_ids,
                                       const Eigen::Vector3d& x_o) {
  std::vector<dataset::BeamRow> out;
  for (size_t b = 0; b < beams.size(); ++b) {
    const Line& l = beams[b];
    out.push_back({beam_ids[b], l.PointAt(l.Parameter(x_o)), l.v});
  }
  return out;
}

double MeanSpanningAngleDeg(const std::vector<ReflectedDot>& reflected_dots,
                            const std::vector<int>& scan_planes, const std::vector<int>& est_beams,
                            const geometry::CameraModel& camera, const Estimate& est) {
  std::map<std::pair<int, int>, Eigen::Vector3d> dot_world;
  for (const auto& r : reflected_dots)
    if (auto x = BackProjectToBoard(camera, est.c2_from_world, r.obs.px))
      dot_world[{r.plane, r.beam}] = *x;
  double sum = 0;
  int cnt = 0;
  for (int p : scan_planes) {
    const auto a = dot_world.find({p, est_beams[0]}), b = dot_world.find({p, est_beams[1]});
    if (a == dot_world.end() || b == dot_world.end()) continue;
    const Line& la = est.beams[est_beams[0]];
    const Line& lb = est.beams[est_beams[1]];
    const Eigen::Vector3d na = la.v.cross(a->second) + la.m, nb = lb.v.cross(b->second) + lb.m;
    double ang = geometry::AngleBetween(na, nb) * common::kDegPerRad;
    if (ang > 90) ang = 180 - ang;
    sum += ang;
    ++cnt;
  }
  return cnt ? sum / cnt : 0;
}

ValidationResult ValidateHeldOutBeams(const Observations& obs,
                                      const std::vector<ReflectedDot>& validation_dots,
                                      const std::vector<std::pair<Step2Kind, int>>& plane_keys,
                                      const std::vector<int>& est_beams,
                                      const std::vector<int>& beam_ids, const MleResult& mle) {
  ValidationResult out;
  const Estimate& est = mle.estimate;
  out.baseline = FitBaseline(est.beams, est_beams, obs.reflected_dots, obs.num_planes, obs.camera,
                             est.c2_from_world);
  auto angular_error = [&](const Line& beam, const Plane& mirror, const Eigen::Vector2d& obs_px,
                           const Eigen::Vector2d& pred_px) {
    const auto h = geometry::IntersectLinePlane(beam, mirror);
    const auto xo = BackProjectToBoard(obs.camera, est.c2_from_world, obs_px);
    const auto xp = BackProjectToBoard(obs.camera, est.c2_from_world, pred_px);
    if (!h || !xo || !xp) return 0.0;
    return geometry::AngleBetween(*xo - *h, *xp - *h) * common::kDegPerRad;
  };
  // Per kept dot, what the joint covariance needs: the prediction's Jacobian over
  // [plane (3), c2 (6), beam (4)] and the dot's own covariance (with its variance factor).
  struct HeldOut {
    ValidationDetail d;
    int plane = 0, beam = 0;
    Eigen::Matrix<double, 2, 13> jac;
    Eigen::Matrix2d noise;
  };
  std::vector<HeldOut> kept;
  for (const auto& vd : validation_dots) {
    if (plane_keys[vd.plane].first != Step2Kind::kScan) continue;
    const Plane& mirror = est.planes[vd.plane];
    const Line& beam = est.beams[vd.beam];
    const auto pred = PredictReflectedDot(obs.camera, est.c2_from_world, beam, mirror);
    const auto pred_b =
        PredictReflectedDot(obs.camera, est.c2_from_world, beam, out.baseline.planes[vd.plane]);
    if (!pred || !pred_b) continue;
    HeldOut h;
    ValidationDetail& d = h.d;
    h.plane = vd.plane;
    h.beam = vd.beam;
    const int j = plane_keys[vd.plane].second;
    d.row = {beam_ids[vd.beam], j, (*pred - vd.obs.px).norm(),
             angular_error(beam, mirror, vd.obs.px, *pred)};
    d.baseline = {beam_ids[vd.beam], j, (*pred_b - vd.obs.px).norm(),
                  angular_error(beam, out.baseline.planes[vd.plane], vd.obs.px, *pred_b)};
    // eq. 10: J Sigma J^T over [plane (3), c2 (6), beam (4)] plus the dot's own covariance.
    const Eigen::MatrixXd joint = mle.JointCovariance(vd.plane);
    std::vector<int> idx = {0, 1, 2};
    for (int k = 0; k < 6; ++k) idx.push_back(3 + mle.OffsetC2() + k);
    for (int k = 0; k < 4; ++k) idx.push_back(3 + mle.OffsetBeam(vd.beam) + k);
    h.jac = CentralDifferenceJacobian(
        [&](const Eigen::Matrix<double, 13, 1>& x) {
          return PredictReflectedDot(
                     obs.camera, TransformFromChart(est.c2_from_world, x.segment<6>(3)),
                     BeamFromChart(beam, x.tail<4>()), PlaneFromChart(mirror, x.head<3>()))
              .value_or(*pred);
        },
        Eigen::Matrix<double, 13, 1>::Zero(), kCentralDifferenceStep);
    Eigen::MatrixXd sub(13, 13);
    for (int a = 0; a < 13; ++a)
      for (int b = 0; b < 13; ++b) sub(a, b) = joint(idx[a], idx[b]);
    // The held-out dot's own covariance with the reflected-dot variance factor of the MLE.
    h.noise = vd.obs.cov_px2 *
              mle.covariance_scale[vd.near_board_edge ? kReflectedDotsNearEdge : kReflectedDots];
    const Eigen::Matrix2d c = h.jac * sub * h.jac.transpose() + h.noise;
    d.observed_px = vd.obs.px;
    d.predicted_px = *pred;
    d.cov_px2 = c;
    const Eigen::Vector2d e = vd.obs.px - *pred;
    d.predicted_sigma_px = std::sqrt(c.trace() / 2);
    d.normalised_error = std::sqrt(e.dot(c.ldlt().solve(e)) / 2);
    kept.push_back(std::move(h));
  }
  std::sort(kept.begin(), kept.end(), [](const HeldOut& a, const HeldOut& b) {
    return std::make_pair(a.d.row.beam, a.d.row.j) < std::make_pair(b.d.row.beam, b.d.row.j);
  });

  // The joint covariance of the stacked errors. Linearised, a dot's error is
  // J_p dx_plane + J_o dx_o + noise over the shared parameters o (c2, beams; mle.h's order) and
  // its plane, with x_plane = own - G^T o (mle.h): J_p own + K dx_o + noise, K = J_o - J_p G^T.
  // Hence C = K Sigma_o K^T + (J_p own_cov J_p^T between dots of one plane) + noise on the
  // diagonal; its diagonal blocks are eq. 10's covariances above.
  const int n = static_cast<int>(kept.size());
  if (n > 0) {
    const int no = static_cast<int>(mle.other_cov.rows());
    Eigen::MatrixXd k_all = Eigen::MatrixXd::Zero(2 * n, no);
    for (int i = 0; i < n; ++i) {
      const HeldOut& h = kept[i];
      Eigen::MatrixXd jo = Eigen::MatrixXd::Zero(2, no);
      jo.middleCols(mle.OffsetC2(), 6) = h.jac.middleCols(3, 6);
      jo.middleCols(mle.OffsetBeam(h.beam), 4) = h.jac.rightCols(4);
      const Eigen::MatrixXd g = Eigen::MatrixXd(mle.plane_gain.middleCols(3 * h.plane, 3));
      k_all.middleRows(2 * i, 2) = jo - h.jac.leftCols(3) * g.transpose();
    }
    Eigen::MatrixXd c = k_all * mle.other_cov * k_all.transpose();
    for (int i = 0; i < n; ++i) {
      c.block<2, 2>(2 * i, 2 * i) += kept[i].noise;
      for (int k = 0; k < n; ++k)
        if (kept[k].plane == kept[i].plane)
          c.block<2, 2>(2 * i, 2 * k) += kept[i].jac.leftCols(3) *
                                         mle.plane_own_cov[kept[i].plane] *
                                         kept[k].jac.leftCols(3).transpose();
    }
    c = (c + c.transpose()) / 2;
    Eigen::VectorXd e(2 * n);
    for (int i = 0; i < n; ++i)
      e.segment<2>(2 * i) = kept[i].d.observed_px - kept[i].d.predicted_px;
    // The noise blocks make C positive definite; LLT fails only on a broken covariance.
    const Eigen::LLT<Eigen::MatrixXd> llt(c);
    const Eigen::VectorXd w = llt.info() == Eigen::Success ? Eigen::VectorXd(llt.matrixL().solve(e))
                                                           : Eigen::VectorXd::Constant(2 * n, NAN);
    for (int i = 0; i < n; ++i) kept[i].d.joint_whitened = w.segment<2>(2 * i);
    out.joint_nees = w.squaredNorm();
    out.joint_cov = std::move(c);
  }

  double s_deg = 0, s_px = 0, sb_deg = 0, sb_px = 0, s_norm = 0;
  for (const HeldOut& h : kept) {
    const ValidationDetail& d = h.d;
    s_deg += d.row.err_deg * d.row.err_deg;
    s_px += d.row.err_px * d.row.err_px;
    sb_deg += d.baseline.err_deg * d.baseline.err_deg;
    sb_px += d.baseline.err_px * d.baseline.err_px;
    s_norm += d.normalised_error * d.normalised_error;
    out.details.push_back(d);
  }
  if (n > 0) {
    out.rms_deg = std::sqrt(s_deg / n);
    out.rms_px = std::sqrt(s_px / n);
    out.rms_baseline_deg = std::sqrt(sb_deg / n);
    out.rms_baseline_px = std::sqrt(sb_px / n);
    out.rms_normalised = std::sqrt(s_norm / n);
  }
  return out;
}

std::vector<WhitenedResidual> WhitenedFitResiduals(const Observations& obs, const MleResult& mle) {
  std::vector<WhitenedResidual> out;
  const Estimate& est = mle.estimate;
  auto add = [&out](int family, int group, const Eigen::Vector2d& px, const Eigen::Matrix2d& cov,
                    const std::optional<Eigen::Vector2d>& pred) {
    if (!pred) return;
    // A (observed - predicted), A = L^-1 with L L^T = cov (the MLE's Whitener, sign flipped).
    const Eigen::Matrix2d l = cov.llt().matrixL();
    out.push_back({family, group, px, l.triangularView<Eigen::Lower>().solve(px - *pred)});
  };
  // The MLE's order: corners, sliding-plane dots, reflected dots.
  const double corner_var = obs.corner_sigma_px * obs.corner_sigma_px;
  for (size_t s = 0; s < obs.corners.size(); ++s) {
    const CornerSet& cs = obs.corners[s];
    const int family = cs.view == BoardView::kC1World   ? kCornersC1World
                       : cs.view == BoardView::kC2World ? kCornersC2World
                                                        : kCornersC1Sliding;
    const geometry::Rigid3d& t = cs.view == BoardView::kC1World   ? est.c1_from_world
                                 : cs.view == BoardView::kC2World ? est.c2_from_world
                                                                  : est.c1_from_sliding[cs.pose];
    const Eigen::Matrix2d cov =
        Eigen::Matrix2d::Identity() * corner_var * mle.covariance_scale[family];
    for (size_t i = 0; i < cs.px.size(); ++i)
      add(family, static_cast<int>(s), cs.px[i], cov,
          obs.camera.Project(t * cs.points_in_board[i]));
  }
  for (const auto& d : obs.sliding_dots)
    add(kSlidingDots, d.pose, d.obs.px, d.obs.cov_px2 * mle.covariance_scale[kSlidingDots],
        PredictSlidingDot(obs.camera, est.c1_from_world, est.c1_from_sliding[d.pose],
                          est.beams[d.beam]));
  for (const auto& d : obs.reflected_dots) {
    const int family = d.near_board_edge ? kReflectedDotsNearEdge : kReflectedDots;
    add(family, d.plane, d.obs.px, d.obs.cov_px2 * mle.covariance_scale[family],
        PredictReflectedDot(obs.camera, est.c2_from_world, est.beams[d.beam], est.planes[d.plane]));
  }
  return out;
}

}  // namespace msmcal::solver

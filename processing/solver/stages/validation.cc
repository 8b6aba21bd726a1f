#include "processing/solver/stages/validation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>

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
  double s_deg = 0, s_px = 0, sb_deg = 0, sb_px = 0, s_norm = 0;
  auto angular_error = [&](const Line& beam, const Plane& mirror, const Eigen::Vector2d& obs_px,
                           const Eigen::Vector2d& pred_px) {
    const auto h = geometry::IntersectLinePlane(beam, mirror);
    const auto xo = BackProjectToBoard(obs.camera, est.c2_from_world, obs_px);
    const auto xp = BackProjectToBoard(obs.camera, est.c2_from_world, pred_px);
    if (!h || !xo || !xp) return 0.0;
    return geometry::AngleBetween(*xo - *h, *xp - *h) * common::kDegPerRad;
  };
  for (const auto& vd : validation_dots) {
    if (plane_keys[vd.plane].first != Step2Kind::kScan) continue;
    const Plane& mirror = est.planes[vd.plane];
    const Line& beam = est.beams[vd.beam];
    const auto pred = PredictReflectedDot(obs.camera, est.c2_from_world, beam, mirror);
    const auto pred_b =
        PredictReflectedDot(obs.camera, est.c2_from_world, beam, out.baseline.planes[vd.plane]);
    if (!pred || !pred_b) continue;
    ValidationDetail d;
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
    const Eigen::MatrixXd jac = CentralDifferenceJacobian(
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
    const Eigen::Matrix2d c =
        jac * sub * jac.transpose() +
        vd.obs.cov_px2 *
            mle.covariance_scale[vd.near_board_edge ? kReflectedDotsNearEdge : kReflectedDots];
    const Eigen::Vector2d e = vd.obs.px - *pred;
    d.predicted_sigma_px = std::sqrt(c.trace() / 2);
    d.normalised_error = std::sqrt(e.dot(c.ldlt().solve(e)) / 2);
    s_deg += d.row.err_deg * d.row.err_deg;
    s_px += d.row.err_px * d.row.err_px;
    sb_deg += d.baseline.err_deg * d.baseline.err_deg;
    sb_px += d.baseline.err_px * d.baseline.err_px;
    s_norm += d.normalised_error * d.normalised_error;
    out.details.push_back(d);
  }
  std::sort(out.details.begin(), out.details.end(), [](const auto& a, const auto& b) {
    return std::make_pair(a.row.beam, a.row.j) < std::make_pair(b.row.beam, b.row.j);
  });
  if (const double n = static_cast<double>(out.details.size()); n > 0) {
    out.rms_deg = std::sqrt(s_deg / n);
    out.rms_px = std::sqrt(s_px / n);
    out.rms_baseline_deg = std::sqrt(sb_deg / n);
    out.rms_baseline_px = std::sqrt(sb_px / n);
    out.rms_normalised = std::sqrt(s_norm / n);
  }
  return out;
}

}  // namespace msmcal::solver

#include "processing/solver/stages/uncertainty.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>

#include "common/units.h"
#include "processing/geometry/mirror_frame.h"
#include "processing/solver/numeric_diff.h"
#include "processing/solver/stages/common.h"

namespace msmcal::solver {
namespace {

using geometry::Plane;
using geometry::Rigid3d;

// -G_p^T (mle.h), 3 x num_other.
Eigen::MatrixXd NegGainT(const MleResult& mle, int p) {
  return Eigen::MatrixXd(-Eigen::MatrixXd(mle.plane_gain.middleCols(3 * p, 3)).transpose());
}

}  // namespace

Mirror0Covariance PropagateMirror0Covariance(const PlaneRoles& roles, const MleResult& mle,
                                             const Rigid3d& world_from_mirror0) {
  Mirror0Covariance out;
  const Estimate& est = mle.estimate;
  const int neutral_index = roles.neutral;
  const std::vector<int>& fast_index = roles.fast_only;
  const std::vector<int>& scan_index = roles.scan;
  auto frame_of = [&](const std::vector<Plane>& planes) {
    return Mirror0FromPlanes(planes, roles);
  };
  const Eigen::Vector3d x_o = world_from_mirror0.translation;
  // Uncertainty of {0} itself: its error phi = [rotation vector (3), dX_O (3)] is a function of
  // the neutral, fast-only and scan planes, phi = sum_k W_k dx_k (central differences). With
  // x_k = own_k - G_k^T o (mle.h), Cov(phi) = sum_k W_k H_k^-1 W_k^T + M Sigma_OO M^T,
  // M = -sum_k W_k G_k^T, and Cov(x_j, phi) = H_j^-1 W_j^T + (-G_j^T) Sigma_OO M^T.
  const int num_other = static_cast<int>(mle.other_cov.rows());
  auto frame_error = [&](const Rigid3d& f) {
    Eigen::Matrix<double, 6, 1> e;
    e.head<3>() =
        geometry::So3Log(f.RotationMatrix() * world_from_mirror0.RotationMatrix().transpose());
    e.tail<3>() = f.translation - x_o;
    return e;
  };
  std::vector<Eigen::Matrix<double, 6, 3>>& frame_w = out.frame_w;
  frame_w.assign(est.planes.size(), Eigen::Matrix<double, 6, 3>::Zero());
  std::vector<int> frame_set = scan_index;
  frame_set.push_back(neutral_index);
  frame_set.insert(frame_set.end(), fast_index.begin(), fast_index.end());
  std::vector<Plane> perturbed = est.planes;
  Eigen::Matrix<double, 6, 6> cov_phi = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::MatrixXd m_phi = Eigen::MatrixXd::Zero(6, num_other);
  for (int p : frame_set) {
    frame_w[p] = CentralDifferenceJacobian(
        [&](const Eigen::Vector3d& h) {
          perturbed[p] = PlaneFromChart(est.planes[p], h);
          return frame_error(frame_of(perturbed));
        },
        Eigen::Vector3d::Zero(), kCentralDifferenceStep);
    perturbed[p] = est.planes[p];
    cov_phi += frame_w[p] * mle.plane_own_cov[p] * frame_w[p].transpose();
    m_phi += frame_w[p] * NegGainT(mle, p);
  }
  out.m_sigma = m_phi * mle.other_cov;  // 6 x num_other
  cov_phi += out.m_sigma * m_phi.transpose();
  out.cov = cov_phi;
  return out;
}

std::vector<dataset::MirrorPlaneRow> ScanPlaneRows(
    const std::vector<std::pair<dataset::Step2Kind, int>>& plane_keys, const PlaneRoles& roles,
    const std::vector<dataset::Trigger>& triggers, const MleResult& mle,
    const Rigid3d& world_from_mirror0, const Mirror0Covariance& m0) {
  std::vector<dataset::MirrorPlaneRow> out;
  const Estimate& est = mle.estimate;
  const Eigen::Vector3d x_o = world_from_mirror0.translation;
  std::map<int, double> t_of_j;
  for (const auto& t : triggers) t_of_j[t.j] = t.t_s;
  auto pose_vec = [&](const Rigid3d& frame, const Plane& p) {
    const auto pose = geometry::PoseFromWorldPlane(frame, p);
    return Eigen::Vector3d(pose.alpha_rad * common::kDegPerRad, pose.beta_rad * common::kDegPerRad,
                           pose.trans_mm);
  };
  const std::vector<int> scan_planes = ScanPlanesByJ(plane_keys, roles);
  for (int p : scan_planes) {
    dataset::MirrorPlaneRow row;
    row.j = plane_keys[p].second;
    row.t_s = t_of_j[row.j];
    row.plane_in_world = est.planes[p];
    const Eigen::Vector3d v = pose_vec(world_from_mirror0, est.planes[p]);
    row.alpha_deg = v(0);
    row.beta_deg = v(1);
    row.trans_mm = v(2);
    // Pose in {0} as a function of the plane (chart) and of {0}'s error phi.
    Eigen::Matrix3d a;
    Eigen::Matrix<double, 3, 6> f;
    a = CentralDifferenceJacobian(
        [&](const Eigen::Vector3d& h) {
          return pose_vec(world_from_mirror0, PlaneFromChart(est.planes[p], h));
        },
        Eigen::Vector3d::Zero(), kCentralDifferenceStep);
    f = CentralDifferenceJacobian(
        [&](const Eigen::Matrix<double, 6, 1>& e) {
          const Rigid3d moved(geometry::So3Exp(e.head<3>()) * world_from_mirror0.RotationMatrix(),
                              x_o + e.tail<3>());
          return pose_vec(moved, est.planes[p]);
        },
        Eigen::Matrix<double, 6, 1>::Zero(), kCentralDifferenceStep);
    const Eigen::Matrix<double, 3, 6> cross = mle.plane_own_cov[p] * m0.frame_w[p].transpose() +
                                              NegGainT(mle, p) * m0.m_sigma.transpose();
    const Eigen::Matrix3d cov = a * mle.plane_cov[p] * a.transpose() + a * cross * f.transpose() +
                                f * cross.transpose() * a.transpose() + f * m0.cov * f.transpose();
    row.sigma_alpha_deg = std::sqrt(std::max(cov(0, 0), 0.0));
    row.sigma_beta_deg = std::sqrt(std::max(cov(1, 1), 0.0));
    row.sigma_trans_mm = std::sqrt(std::max(cov(2, 2), 0.0));
    out.push_back(row);
  }
  return out;
}

}  // namespace msmcal::solver

#pragma once
// Stage: uncertainty (MSM paper Sec. V-A4, eq. 8, carried to {0}). The covariance of {0} itself,
// propagated from the neutral, fast-only and scan planes' covariances (with their correlation
// through the shared parameters), and the scan planes' poses in {0} with their standard
// deviations. Derivatives by central differences (numeric_diff.h).

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/geometry/rigid3.h"
#include "processing/solver/mle.h"
#include "processing/solver/stages/mirror0.h"

namespace msmcal::solver {

// {0}'s error phi = [rotation vector (rad, in {W}: R_true = Exp(-e) R_est), dX_O (mm)] as a
// linear function of the planes' chart errors, phi = sum_k W_k dx_k, and its covariance.
struct Mirror0Covariance {
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Zero();
  std::vector<Eigen::Matrix<double, 6, 3>> frame_w;  // W_k per plane (zero for planes not used)
  Eigen::MatrixXd m_sigma;  // M Sigma_OO, 6 x num_other (cross term with the shared parameters)
};
Mirror0Covariance PropagateMirror0Covariance(const PlaneRoles& roles, const MleResult& mle,
                                             const geometry::Rigid3d& world_from_mirror0);

// mirror_planes.csv: each scan plane's pose in {0} (by ascending j) with its standard
// deviations, from the plane's covariance, {0}'s and their cross term.
std::vector<dataset::MirrorPlaneRow> ScanPlaneRows(
    const std::vector<std::pair<dataset::Step2Kind, int>>& plane_keys, const PlaneRoles& roles,
    const std::vector<dataset::Trigger>& triggers, const MleResult& mle,
    const geometry::Rigid3d& world_from_mirror0, const Mirror0Covariance& mirror0_cov);

}  // namespace msmcal::solver

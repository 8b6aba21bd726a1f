#include "processing/solver/home_frame.h"

#include <Eigen/Dense>

#include "processing/geometry/mirror_frame.h"
#include "processing/solver/model.h"

namespace msmcal::solver {

Eigen::Vector3d HomeOrigin(const geometry::Plane& neutral,
                           const std::vector<geometry::Plane>& planes) {
  // X = d0 n0 + T u; residual of plane j: n_j . X - d_j = (n_j^T T) u - (d_j - d0 n_j . n0).
  const Eigen::Vector3d n0 = neutral.n.normalized();
  const Eigen::Vector3d base = neutral.d * n0;
  const Eigen::Matrix<double, 3, 2> t = TangentBasis(n0);
  Eigen::Matrix2d ata = Eigen::Matrix2d::Zero();
  Eigen::Vector2d atb = Eigen::Vector2d::Zero();
  for (const auto& p : planes) {
    const Eigen::Vector2d a = t.transpose() * p.n;
    ata += a * a.transpose();
    atb += a * (p.d - p.n.dot(base));
  }
  // Pseudo-inverse: unconstrained directions stay at the base point.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(ata);
  Eigen::Vector2d u = Eigen::Vector2d::Zero();
  const double max_ev = std::max(es.eigenvalues()(1), 0.0);
  for (int k = 0; k < 2; ++k) {
    const double ev = es.eigenvalues()(k);
    if (ev > 1e-10 * max_ev && ev > 1e-14) {
      const Eigen::Vector2d e = es.eigenvectors().col(k);
      u += e * (e.dot(atb) / ev);
    }
  }
  return base + t * u;
}

geometry::Rigid3d HomeFrame(const geometry::Plane& neutral, const Eigen::Vector3d& fast_axis,
                            const std::vector<geometry::Plane>& scan_planes) {
  return geometry::MirrorHomeFrame(neutral.n, fast_axis, HomeOrigin(neutral, scan_planes));
}

geometry::Rigid3d ConventionalTruthFrame(const geometry::Rigid3d& world_from_mirror0_truth,
                                         const std::vector<geometry::Plane>& true_scan_planes) {
  const Eigen::Matrix3d r = world_from_mirror0_truth.RotationMatrix();
  const Eigen::Vector3d n0 = r.col(2);
  const geometry::Plane neutral{n0, n0.dot(world_from_mirror0_truth.translation)};
  return geometry::Rigid3d(r, HomeOrigin(neutral, true_scan_planes));
}

}  // namespace msmcal::solver

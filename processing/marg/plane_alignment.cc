#include "processing/marg/plane_alignment.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace msmcal::marg {

std::string PlaneAlignmentOptions::Validate() const {
  if (min_samples < 3) return "min_samples=" + std::to_string(min_samples) + " must be >= 3";
  if (!(min_relative_radius >= 0)) return "min_relative_radius must be >= 0";
  if (!(min_turn_deg >= 0 && min_turn_deg <= 360)) {
    return "min_turn_deg=" + std::to_string(min_turn_deg) + " must be in [0, 360]";
  }
  return "";
}

const char* ToString(PlaneAlignmentStatus status) {
  switch (status) {
    case PlaneAlignmentStatus::kOk:
      return "ok";
    case PlaneAlignmentStatus::kTooFewSamples:
      return "too_few_samples";
    case PlaneAlignmentStatus::kNoCircle:
      return "no_circle";
    case PlaneAlignmentStatus::kPartialTurn:
      return "partial_turn";
    case PlaneAlignmentStatus::kNonFinite:
      return "non_finite";
  }
  return "unknown";
}

Eigen::Matrix3d AlignmentMatrix(double roll, double pitch) {
  const double cr = std::cos(roll), sr = std::sin(roll);
  const double cp = std::cos(pitch), sp = std::sin(pitch);
  Eigen::Matrix3d rx, ry;
  rx << 1, 0, 0, 0, cr, -sr, 0, sr, cr;
  ry << cp, 0, sp, 0, 1, 0, -sp, 0, cp;
  return ry * rx;
}

void AlignmentAngles(const Eigen::Vector3d& n, double* roll, double* pitch) {
  // R_x(roll) n has zero y: roll = atan2(n_y, n_z); then R_y(pitch) [n_x, 0, r] has zero x.
  *roll = std::atan2(n.y(), n.z());
  const double r = std::hypot(n.y(), n.z());
  *pitch = std::atan2(-n.x(), r);
}

PlaneAlignmentResult FitPlaneAlignment(const std::vector<Eigen::Vector3d>& samples,
                                       const PlaneAlignmentOptions& options) {
  if (const std::string err = options.Validate(); !err.empty()) {
    throw std::invalid_argument("PlaneAlignmentOptions: " + err);
  }
  PlaneAlignmentResult res;
  if (static_cast<int>(samples.size()) < options.min_samples) {
    res.status = PlaneAlignmentStatus::kTooFewSamples;
    res.message = std::to_string(samples.size()) + " samples, at least " +
                  std::to_string(options.min_samples) + " needed";
    return res;
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : samples) {
    if (!p.allFinite()) {
      res.status = PlaneAlignmentStatus::kNonFinite;
      res.message = "samples contain NaN or infinite values";
      return res;
    }
    mean += p;
  }
  mean /= static_cast<double>(samples.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : samples) cov += (p - mean) * (p - mean).transpose();
  cov /= static_cast<double>(samples.size());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  Eigen::Vector3d n = es.eigenvectors().col(0);
  if (n.z() < 0) n = -n;
  res.normal = n;
  res.circle_centre = mean;
  res.rms_plane_residual = std::sqrt(std::max(0.0, es.eigenvalues()(0)));
  res.circle_radius = std::sqrt(std::max(0.0, es.eigenvalues()(1) + es.eigenvalues()(2)));
  // Eq. 1 form (undefined for a vertical plane; then alpha, beta are infinite).
  res.alpha = -n.x() / n.z();
  res.beta = -n.y() / n.z();
  res.gamma = n.dot(mean) / n.z();
  AlignmentAngles(n, &res.roll_rad, &res.pitch_rad);
  res.alignment = AlignmentMatrix(res.roll_rad, res.pitch_rad);

  const double scale = std::max(mean.norm(), res.circle_radius);
  std::ostringstream os;
  os.precision(4);
  if (!(res.circle_radius > options.min_relative_radius * scale) ||
      es.eigenvalues()(1) < 0.05 * es.eigenvalues()(2)) {
    res.status = PlaneAlignmentStatus::kNoCircle;
    os << "the samples trace no circle (radius " << res.circle_radius << " vs magnitude " << scale
       << "): the fixed plane must be inclined so that the vector is not along the rotation axis";
    res.message = os.str();
    return res;
  }
  // Circle centre in the plane (Kasa fit: x^2 + y^2 + D x + E y + F = 0 in plane coordinates,
  // exact for a partial arc, where the mean is not the centre), then the angular coverage as
  // 360 deg minus the largest gap between azimuths about that centre.
  const Eigen::Vector3d e1 = es.eigenvectors().col(2);
  const Eigen::Vector3d e2 = n.cross(e1);
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  const double s = res.circle_radius;
  for (const auto& p : samples) {
    const Eigen::Vector3d d = p - mean;
    const double x = d.dot(e1) / s, y = d.dot(e2) / s;
    const Eigen::Vector3d row(x, y, 1);
    ata += row * row.transpose();
    atb -= row * (x * x + y * y);
  }
  const Eigen::Vector3d def = ata.ldlt().solve(atb);
  const double cx = -def(0) / 2, cy = -def(1) / 2;
  res.circle_centre = mean + s * (cx * e1 + cy * e2);
  res.circle_radius = s * std::sqrt(std::max(0.0, cx * cx + cy * cy - def(2)));
  std::vector<double> az;
  az.reserve(samples.size());
  for (const auto& p : samples) {
    const Eigen::Vector3d d = p - res.circle_centre;
    az.push_back(std::atan2(d.dot(e2), d.dot(e1)));
  }
  std::sort(az.begin(), az.end());
  double gap = az.front() + 2 * std::numbers::pi - az.back();
  for (size_t i = 1; i < az.size(); ++i) gap = std::max(gap, az[i] - az[i - 1]);
  res.turn_deg = 360.0 - gap * 180.0 / std::numbers::pi;
  if (res.turn_deg < options.min_turn_deg) {
    res.status = PlaneAlignmentStatus::kPartialTurn;
    os << "the rotation covers " << res.turn_deg << " deg of the circle, at least "
       << options.min_turn_deg << " deg needed: turn the board through a full turn";
    res.message = os.str();
    return res;
  }
  res.status = PlaneAlignmentStatus::kOk;
  os << "plane alignment: roll " << res.roll_rad * 180 / std::numbers::pi << " deg, pitch "
     << res.pitch_rad * 180 / std::numbers::pi << " deg, circle radius " << res.circle_radius
     << ", out-of-plane RMS " << res.rms_plane_residual;
  res.message = os.str();
  return res;
}

}  // namespace msmcal::marg

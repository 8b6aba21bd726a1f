#include "processing/marg/coverage.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include "common/units.h"

namespace msmcal::marg {

std::string CoverageOptions::Validate() const {
  if (num_cells < 2) return "num_cells=" + std::to_string(num_cells) + " must be >= 2";
  if (min_samples_per_cell < 1) {
    return "min_samples_per_cell=" + std::to_string(min_samples_per_cell) + " must be >= 1";
  }
  return "";
}

std::vector<Eigen::Vector3d> FibonacciSphere(int n) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(static_cast<size_t>(n));
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = golden * i;
    out.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
  }
  return out;
}

CoverageResult SphereCoverage(const std::vector<Eigen::Vector3d>& directions,
                              const CoverageOptions& options) {
  if (const std::string err = options.Validate(); !err.empty()) {
    throw std::invalid_argument("CoverageOptions: " + err);
  }
  CoverageResult result;
  result.cell_centres = FibonacciSphere(options.num_cells);
  result.counts.assign(result.cell_centres.size(), 0);
  for (const auto& d : directions) {
    const double norm = d.norm();
    if (!(norm > 0) || !std::isfinite(norm)) continue;
    const Eigen::Vector3d u = d / norm;
    int best = 0;
    double best_dot = -2;
    for (size_t c = 0; c < result.cell_centres.size(); ++c) {
      const double dot = u.dot(result.cell_centres[c]);
      if (dot > best_dot) {
        best_dot = dot;
        best = static_cast<int>(c);
      }
    }
    ++result.counts[static_cast<size_t>(best)];
  }
  for (size_t c = 0; c < result.counts.size(); ++c) {
    if (result.counts[c] >= options.min_samples_per_cell) {
      ++result.covered_cells;
    } else {
      result.missing_directions.push_back(result.cell_centres[c]);
    }
  }
  result.fraction = static_cast<double>(result.covered_cells) / options.num_cells;
  return result;
}

std::string DescribeDirection(const Eigen::Vector3d& direction) {
  const Eigen::Vector3d u = direction.normalized();
  std::string axes;
  const char* names[3] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    if (std::abs(u(i)) >= 0.38) {  // more than ~22 deg towards that axis
      if (!axes.empty()) axes += " ";
      axes += (u(i) > 0 ? "+" : "-");
      axes += names[i];
    }
  }
  const double az = common::RadToDeg(std::atan2(u.y(), u.x()));
  const double el = common::RadToDeg(std::asin(std::clamp(u.z(), -1.0, 1.0)));
  char buf[64];
  std::snprintf(buf, sizeof(buf), " (az %.0f deg, el %.0f deg)", az, el);
  return axes + buf;
}

}  // namespace msmcal::marg

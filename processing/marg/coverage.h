#pragma once
// Sphere coverage of a set of measured directions: which orientations a free-rotation capture
// has visited, so that a guided capture can tell the operator what is still missing.
//
// The unit sphere is divided into `num_cells` nearly equal-area cells centred on a Fibonacci
// lattice (Voronoi cells); a cell is covered when at least `min_samples_per_cell` directions fall
// into it (nearest cell centre). Coverage = covered cells / all cells: a full sphere gives ~1, one
// hemisphere ~0.55 (cells straddling the boundary count as covered).

#include <Eigen/Core>
#include <string>
#include <vector>

namespace msmcal::marg {

struct CoverageOptions {
  int num_cells = 100;
  int min_samples_per_cell = 1;
  std::string Validate() const;  // "" if valid
};

struct CoverageResult {
  double fraction = 0;  // covered / num_cells, in [0, 1]
  int covered_cells = 0;
  std::vector<Eigen::Vector3d> cell_centres;        // unit vectors, one per cell
  std::vector<int> counts;                          // samples per cell
  std::vector<Eigen::Vector3d> missing_directions;  // centres of uncovered cells
};

// Cell centres of the Fibonacci lattice with n points (unit vectors).
std::vector<Eigen::Vector3d> FibonacciSphere(int n);

// Coverage of `directions` (need not be unit; zero vectors are ignored). Throws
// std::invalid_argument for invalid options.
CoverageResult SphereCoverage(const std::vector<Eigen::Vector3d>& directions,
                              const CoverageOptions& options = {});

// Human-readable hint for a missing direction in the sensor frame, e.g. "+x +z (az 45 deg, el
// 30 deg)": which sensor axis should point along the measured field.
std::string DescribeDirection(const Eigen::Vector3d& direction);

}  // namespace msmcal::marg

#pragma once
// A small, seeded synthetic mirror-calibration scene at the geometric level (no images): true
// transforms, beams and planes, and noisy observations drawn from the stated covariances. For
// unit tests (recovered truth, covariance honesty) and the solver benchmarks.
//
// Geometry ({W} = world board, Z into the board, camera side z < 0): the mirror sits 200 mm in
// front of the board; beams travel roughly along -X_W, pass through the sliding board (poses
// along the beams), hit the mirror, and are reflected onto the world board.

#include <cstdint>
#include <vector>

#include "processing/solver/model.h"

namespace msmcal::solver {

struct SyntheticSceneOptions {
  int num_planes = 20;
  int num_poses = 5;
  // Horizontal incidence angle of each beam relative to -X_W (deg); the first `num_estimate` are
  // fitted, the rest are held out for validation.
  std::vector<double> beam_azimuth_deg = {0.0, 25.0, 12.0};
  std::vector<double> beam_elevation_deg = {0.0, 0.0, 8.0};
  int num_estimate = 2;
  double mirror_amplitude_deg = 4.0;  // mirror tilt range (uniform +-)
  double mirror_trans_mm = 0.3;       // out-of-plane translation range (uniform +-)
  double corner_sigma_px = 0.1;
  double dot_sigma_px = 0.15;  // dot covariances are random with about this size
  uint64_t seed = 1;
};

struct SyntheticScene {
  Estimate truth;
  Observations obs;                           // reflected dots of the estimate beams only
  std::vector<ReflectedDot> validation_dots;  // reflected dots of the held-out beams
  std::vector<int> estimate_beams, validate_beams;
  Eigen::Vector3d rotation_centre_in_world = Eigen::Vector3d::Zero();
};

SyntheticScene MakeSyntheticScene(const SyntheticSceneOptions& options);

}  // namespace msmcal::solver

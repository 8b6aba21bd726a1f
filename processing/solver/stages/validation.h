#pragma once
// Stage: validation (MSM paper Sec. V-B, Table I). The held-out beams' reflected dots are
// predicted from the estimate (and from the baseline model of ref. [26]) and compared with the
// measured ones, in pixels, in angle, and normalised by the predicted covariance (eq. 10). Also
// the result's summary figures: the beams at {0}'s origin and the estimate beams' spanning
// angle on the scan planes.

#include <utility>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/solver/initialise.h"
#include "processing/solver/mle.h"
#include "processing/solver/model.h"
#include "processing/solver/solve_types.h"

namespace msmcal::solver {

// beams.csv: every beam, its point nearest to {0}'s origin `x_o` (in {W}), and its direction.
std::vector<dataset::BeamRow> BeamRows(const std::vector<geometry::Line>& beams,
                                       const std::vector<int>& beam_ids,
                                       const Eigen::Vector3d& x_o);

// Mean angle (deg, folded into [0, 90]) between the light-path planes of the first two
// estimate beams over `scan_planes` (a plane counts if both have a reflected dot on it).
double MeanSpanningAngleDeg(const std::vector<ReflectedDot>& reflected_dots,
                            const std::vector<int>& scan_planes,
                            const std::vector<int>& estimate_beams,
                            const geometry::CameraModel& camera, const Estimate& est);

struct ValidationResult {
  BaselineModel baseline;
  std::vector<ValidationDetail> details;  // by (beam id, j)
  double rms_deg = 0, rms_px = 0;
  double rms_baseline_deg = 0, rms_baseline_px = 0;
  double rms_normalised = 0;
  // e^T C^-1 e over every held-out dot's error stacked, C their joint covariance (the sum of the
  // squared joint_whitened components): chi2(2N) when the covariances are honest.
  double joint_nees = 0;
  // That joint covariance (px^2, 2N x 2N, dots in the order of `details`); its 2x2 diagonal
  // blocks are the dots' cov_px2.
  Eigen::MatrixXd joint_cov;
};
// The held-out dots on scan planes (`validation_dots`) against the estimate in `mle` and the
// baseline fitted to the estimate beams' dots (obs.reflected_dots). Each dot's covariance is
// eq. 10's; the joint covariance of all of them adds the cross terms of the parameters they
// share (c2_from_world, their beam, their plane: one beam error moves every dot of the beam).
ValidationResult ValidateHeldOutBeams(
    const Observations& obs, const std::vector<ReflectedDot>& validation_dots,
    const std::vector<std::pair<dataset::Step2Kind, int>>& plane_keys,
    const std::vector<int>& estimate_beams, const std::vector<int>& beam_ids, const MleResult& mle);

// Every residual the MLE fitted (corners of each board view, sliding-plane dots, reflected dots),
// at its estimate, whitened by the covariance the MLE used for it (WhitenedResidual). A residual
// whose prediction fails (a point behind the camera) is left out.
std::vector<WhitenedResidual> WhitenedFitResiduals(const Observations& obs, const MleResult& mle);

}  // namespace msmcal::solver

#pragma once
// Hall-sensor models that map the foreground field B (uT, background removed) to the mirror
// pose y = (alpha_deg, beta_deg, trans_mm) in {0}, fitted jointly with the time offset dt
// (MSM paper eqs. 12-14):  min_{A, dt} sum_j || f(A, B(t_j + dt)) - y_j ||^2.
//
// Every model is linear in its parameters A (3 x F) given dt, so the fit is a variable
// projection: for each dt the optimal A is a linear least-squares solution and the cost
// J(dt) = min_A sum ||.||^2 is a smooth 1-D function (the field profiles are C1). dt is found by
// a grid scan over the search window (the cross-correlation-like global start) and refined by
// golden-section search around the best grid point.
//
// Models:
// - kLinear (eq. 12): features [B; 1].
// - kSine (eq. 13): features [sin(Phi_k); 1], Phi_k = 2 pi f_k tau + phi_k, where tau is the
//   time the reading belongs to (the paper's B^{-1}: reading -> time), f_k the frequency that
//   dominates Hall axis k (the fast or the slow drive frequency, chosen from the data), phi_k its
//   phase, measured from the foreground profile. See docs/hall-calibration.md.
// - kQuadratic (ours): features [1, b, b (x) b] with b = B / scale: the magnet's dipole field is a
//   smooth nonlinear function of the pose, and its inverse is close to quadratic over the
//   scan range; 10 features.
// - kCubic (ours): all monomials of b up to degree 3; 20 features. Needs more poses (> 20) and
//   is the most faithful to a strongly nonlinear magnet geometry.

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

namespace msmcal::hall {

enum class HallModelKind { kLinear, kSine, kQuadratic, kCubic };
const char* ToString(HallModelKind kind);  // "linear" | "sine" | "quadratic" | "cubic"
bool ParseHallModelKind(const std::string& text, HallModelKind* kind);

struct HallModel {
  HallModelKind kind = HallModelKind::kLinear;
  Eigen::MatrixXd a;          // 3 x F
  double delta_t_s = 0;       // pose at t <-> field at t + delta_t
  double field_scale_uT = 1;  // kQuadratic: b = B / scale
  Eigen::Vector3d sine_frequency_hz = Eigen::Vector3d::Zero();  // kSine
  Eigen::Vector3d sine_phase_rad = Eigen::Vector3d::Zero();     // kSine

  int FeatureCount() const;
  // Features of foreground field `b` that belongs to generator time `tau`.
  void Features(const Eigen::Vector3d& b, double tau, double* out) const;
  // Pose (alpha_deg, beta_deg, trans_mm) at generator time tau - delta_t from the foreground
  // field read at generator time tau.
  Eigen::Vector3d Predict(const Eigen::Vector3d& b, double tau) const;
};

// One calibration target: the pose at trigger time t_s (pattern time, seconds).
struct PoseSample {
  double t_s = 0;
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();  // alpha_deg, beta_deg, trans_mm
  // 1-sigma of the measured pose, same units (the solver's MLE covariance, mirror_planes.csv
  // sigma_*); zero when unknown (poses taken from a simulator's truth).
  Eigen::Vector3d sigma = Eigen::Vector3d::Zero();
};

// Foreground field as a function of generator time (periodic in the pattern period).
using FieldFunction = std::function<Eigen::Vector3d(double t_s)>;

struct HallFitOptions {
  double delta_t_min_s = -0.01;
  double delta_t_max_s = 0.01;
  double grid_step_s = 50e-6;
  double tolerance_s = 1e-8;
  // Frequencies the sine model may pick per axis (the drive frequencies).
  double fast_frequency_hz = 0;
  double slow_frequency_hz = 0;
  double pattern_period_s = 0;
  std::string Validate(HallModelKind kind) const;
};

struct HallFitResult {
  HallModel model;
  Eigen::Vector3d train_rms = Eigen::Vector3d::Zero();  // per output
  double cost = 0;                                      // sum of squared residuals
  int samples = 0;
};

// Fits `kind` and dt. Throws std::invalid_argument for bad options or too few samples
// (need more samples than features).
HallFitResult FitHallModel(HallModelKind kind, const std::vector<PoseSample>& samples,
                           const FieldFunction& foreground, const HallFitOptions& options);

// The cost J(dt) = min_A sum ||f(A, B(t_j + dt)) - y_j||^2 of `kind` on a grid over the search
// window [options.delta_t_min_s, options.delta_t_max_s] with options.grid_step_s (both ends
// included), the model set up as FitHallModel sets it up (field scale, sine phases). What the
// global scan of FitHallModel minimises, for judging whether the minimum is unique.
struct DeltaTProfile {
  HallModelKind kind = HallModelKind::kLinear;
  std::vector<double> dt_s;  // ascending
  std::vector<double> cost;  // one per dt_s
  int residual_dof = 0;      // 3 * (samples - features): the residual's degrees of freedom
};
// Throws std::invalid_argument like FitHallModel.
DeltaTProfile ProfileDeltaT(HallModelKind kind, const std::vector<PoseSample>& samples,
                            const FieldFunction& foreground, const HallFitOptions& options);

// RMS per output of `model` on `samples` with `foreground`.
Eigen::Vector3d EvaluateRms(const HallModel& model, const std::vector<PoseSample>& samples,
                            const FieldFunction& foreground);

}  // namespace msmcal::hall

#include "processing/marg/ellipsoid.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "common/number_format.h"

namespace msmcal::marg {
namespace {

std::string Fmt(double v) { return common::FormatSignificant(v, 4); }

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) {
    m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  return m;
}

// Symmetric 3x3 from its 6 parameters (a00 a11 a22 a01 a02 a12) and back.
Eigen::Matrix3d SymFromParams(const Eigen::Matrix<double, 6, 1>& p) {
  Eigen::Matrix3d a;
  a << p(0), p(3), p(4), p(3), p(1), p(5), p(4), p(5), p(2);
  return a;
}
Eigen::Matrix<double, 6, 1> ParamsFromSym(const Eigen::Matrix3d& a) {
  Eigen::Matrix<double, 6, 1> p;
  p << a(0, 0), a(1, 1), a(2, 2), a(0, 1), a(0, 2), a(1, 2);
  return p;
}

struct Refinement {
  Eigen::Vector3d centre;
  Eigen::Matrix3d a;  // unit-sphere map (symmetric)
  double condition = 0;
  int iterations = 0;
};

// Levenberg-Marquardt on r_i = |A (u_i - c)| - 1 over 9 parameters (c, symmetric A), in
// normalised coordinates. Analytic Jacobian.
Refinement RefineRadial(const std::vector<Eigen::Vector3d>& u, const Eigen::Vector3d& c0,
                        const Eigen::Matrix3d& a0, int max_iterations) {
  using Vec9 = Eigen::Matrix<double, 9, 1>;
  using Mat9 = Eigen::Matrix<double, 9, 9>;
  Vec9 x;
  x << c0, ParamsFromSym(a0);
  auto cost_and_normal = [&](const Vec9& p, Mat9* jtj, Vec9* jtr) {
    const Eigen::Vector3d c = p.head<3>();
    const Eigen::Matrix3d a = SymFromParams(p.tail<6>());
    double cost = 0;
    if (jtj) jtj->setZero();
    if (jtr) jtr->setZero();
    for (const auto& ui : u) {
      const Eigen::Vector3d d = ui - c;
      const Eigen::Vector3d v = a * d;
      const double n = v.norm();
      const double r = n - 1;
      cost += r * r;
      if (!jtj) continue;
      const Eigen::RowVector3d g =
          n > 0 ? Eigen::RowVector3d(v.transpose() / n) : Eigen::RowVector3d::Zero();
      Eigen::Matrix<double, 1, 9> j;
      j.head<3>() = -g * a;
      // dv/da00 = (d0,0,0), da11 = (0,d1,0), da22 = (0,0,d2), da01 = (d1,d0,0),
      // da02 = (d2,0,d0), da12 = (0,d2,d1).
      j(3) = g(0) * d(0);
      j(4) = g(1) * d(1);
      j(5) = g(2) * d(2);
      j(6) = g(0) * d(1) + g(1) * d(0);
      j(7) = g(0) * d(2) + g(2) * d(0);
      j(8) = g(1) * d(2) + g(2) * d(1);
      *jtj += j.transpose() * j;
      *jtr += j.transpose() * r;
    }
    return cost;
  };
  Mat9 jtj;
  Vec9 jtr;
  double cost = cost_and_normal(x, &jtj, &jtr);
  double lambda = 1e-4;
  int it = 0;
  for (; it < max_iterations; ++it) {
    bool improved = false;
    for (int tries = 0; tries < 20; ++tries) {
      Mat9 damped = jtj;
      damped.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
      const Vec9 step = damped.ldlt().solve(-jtr);
      const Vec9 candidate = x + step;
      const double new_cost = cost_and_normal(candidate, nullptr, nullptr);
      if (std::isfinite(new_cost) && new_cost <= cost) {
        const double rel = (cost - new_cost) / std::max(cost, 1e-300);
        x = candidate;
        cost = cost_and_normal(x, &jtj, &jtr);
        lambda = std::max(lambda * 0.3, 1e-12);
        improved = true;
        if (rel < 1e-14 || step.norm() < 1e-13) it = max_iterations;
        break;
      }
      lambda *= 10;
    }
    if (!improved) break;
  }
  Refinement out;
  out.centre = x.head<3>();
  out.a = SymFromParams(x.tail<6>());
  Eigen::SelfAdjointEigenSolver<Mat9> es(jtj);
  const double lo = es.eigenvalues()(0), hi = es.eigenvalues()(8);
  out.condition = lo > 0 ? hi / lo : std::numeric_limits<double>::infinity();
  out.iterations = std::min(it, max_iterations);
  return out;
}

// The unconstrained algebraic fit (smallest eigenvector of the scatter matrix), in the design
// order [a b c f g h p q r d] of FitQuadricLiGriffiths.
Eigen::Matrix<double, 10, 1> UnconstrainedQuadric(const std::vector<Eigen::Vector3d>& u) {
  Eigen::Matrix<double, 10, 10> s = Eigen::Matrix<double, 10, 10>::Zero();
  for (const auto& p : u) {
    const double x = p.x(), y = p.y(), z = p.z();
    Eigen::Matrix<double, 10, 1> row;
    row << x * x, y * y, z * z, 2 * y * z, 2 * x * z, 2 * x * y, 2 * x, 2 * y, 2 * z, 1;
    s += row * row.transpose();
  }
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 10, 10>>(s).eigenvectors().col(0);
}

// RMS Sampson distance Q(u) / |grad Q(u)| of a quadric u^T M u + 2 b^T u + d = 0.
double SampsonRms(const Eigen::Matrix3d& m, const Eigen::Vector3d& b, double d,
                  const std::vector<Eigen::Vector3d>& u) {
  double sum = 0;
  for (const auto& p : u) {
    const double q = p.dot(m * p) + 2 * b.dot(p) + d;
    const double g = (2 * (m * p + b)).norm();
    sum += g > 0 ? (q / g) * (q / g) : 0;
  }
  return std::sqrt(sum / std::max<size_t>(1, u.size()));
}

// Whether the samples lie on another kind of quadric: the unconstrained fit is not an ellipsoid
// and explains the samples clearly better (3x smaller Sampson distance) than the best ellipsoid.
// On a small patch both fit to the noise level and this stays silent (the conditioning check
// reports it instead).
bool OtherQuadricFitsBetter(const std::vector<Eigen::Vector3d>& u, const Eigen::Vector3d& centre,
                            const Eigen::Matrix3d& w, std::string* why) {
  const Eigen::Matrix<double, 10, 1> v = UnconstrainedQuadric(u);
  Eigen::Matrix3d m;
  m << v(0), v(5), v(4), v(5), v(1), v(3), v(4), v(3), v(2);
  const Eigen::Vector3d l = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(m).eigenvalues();
  const double tol = 1e-6 * l.cwiseAbs().maxCoeff();
  if (l(0) > tol || l(2) < -tol) return false;
  const double other = SampsonRms(m, v.segment<3>(6), v(9), u);
  const double ellipsoid = SampsonRms(w, -w * centre, centre.dot(w * centre) - 1, u);
  if (!(ellipsoid > 3 * other + 1e-12)) return false;
  *why = "samples lie on a quadric that is not an ellipsoid (eigenvalues of its quadratic part " +
         Fmt(l(0)) + ", " + Fmt(l(1)) + ", " + Fmt(l(2)) + "; distance RMS " + Fmt(other) + " vs " +
         Fmt(ellipsoid) + " for the best ellipsoid, normalised units)";
  return true;
}

}  // namespace

const char* ToString(EllipsoidFitStatus status) {
  switch (status) {
    case EllipsoidFitStatus::kOk:
      return "ok";
    case EllipsoidFitStatus::kTooFewSamples:
      return "too_few_samples";
    case EllipsoidFitStatus::kDegenerate:
      return "degenerate";
    case EllipsoidFitStatus::kNotEllipsoid:
      return "not_ellipsoid";
    case EllipsoidFitStatus::kNonFinite:
      return "non_finite";
  }
  return "unknown";
}

Eigen::Matrix4d QuadricMatrix(const QuadricCoefficients& q) {
  Eigen::Matrix4d s;
  s << 2 * q.A, q.D, q.F, q.G,  //
      q.D, 2 * q.B, q.E, q.H,   //
      q.F, q.E, 2 * q.C, q.J,   //
      q.G, q.H, q.J, 2 * q.K;
  return 0.5 * s;
}

double EvaluateQuadric(const QuadricCoefficients& q, const Eigen::Vector3d& p) {
  const double x = p.x(), y = p.y(), z = p.z();
  return q.A * x * x + q.B * y * y + q.C * z * z + q.D * x * y + q.E * y * z + q.F * x * z +
         q.G * x + q.H * y + q.J * z + q.K;
}

Eigen::Matrix3d Ellipsoid::UnitSphereMap() const {
  return axes * semi_axes.cwiseInverse().asDiagonal() * axes.transpose();
}

double Ellipsoid::MeanRadius() const { return std::cbrt(semi_axes.prod()); }

double Ellipsoid::RadialResidual(const Eigen::Vector3d& x) const {
  return (UnitSphereMap() * (x - centre)).norm() - 1.0;
}

bool Ellipsoid::FromCentreShape(const Eigen::Vector3d& c, const Eigen::Matrix3d& shape,
                                Ellipsoid* out) {
  const Eigen::Matrix3d w = 0.5 * (shape + shape.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(w);
  if (es.info() != Eigen::Success || !(es.eigenvalues()(0) > 0)) return false;
  out->centre = c;
  out->shape = w;
  out->axes = es.eigenvectors();
  if (out->axes.determinant() < 0) out->axes.col(2) *= -1;
  out->semi_axes = es.eigenvalues().cwiseSqrt().cwiseInverse();
  return true;
}

bool EllipsoidFromQuadric(const QuadricCoefficients& q, Ellipsoid* out, std::string* why) {
  const Eigen::Matrix4d s = QuadricMatrix(q);
  const Eigen::Matrix3d m3 = s.topLeftCorner<3, 3>();
  const Eigen::Vector3d b = s.topRightCorner<3, 1>();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(m3);
  const Eigen::Vector3d ev = es.eigenvalues();
  if (!(ev(0) > 0 || ev(2) < 0)) {
    if (why) {
      *why = "quadratic part is not definite (eigenvalues " + Fmt(ev(0)) + ", " + Fmt(ev(1)) +
             ", " + Fmt(ev(2)) + "): not an ellipsoid";
    }
    return false;
  }
  // Eqs. 9-11: centre and the translated constant term L.
  const Eigen::Vector3d c = -m3.ldlt().solve(b);
  const double l = s(3, 3) + b.dot(c);
  // Eqs. 12-15: canonical form Y = x^T W x = 1 with W = -M3 / L.
  const Eigen::Matrix3d w = -m3 / l;
  if (!Ellipsoid::FromCentreShape(c, w, out)) {
    if (why)
      *why = "canonical form is not positive definite (imaginary ellipsoid, L = " + Fmt(l) + ")";
    return false;
  }
  return true;
}

QuadricCoefficients QuadricFromEllipsoid(const Ellipsoid& e) {
  // (x-c)^T W (x-c) - 1 = x^T W x - 2 c^T W x + c^T W c - 1.
  const Eigen::Matrix3d& w = e.shape;
  const Eigen::Vector3d lin = -2 * w * e.centre;
  QuadricCoefficients q;
  q.A = w(0, 0);
  q.B = w(1, 1);
  q.C = w(2, 2);
  q.D = 2 * w(0, 1);
  q.E = 2 * w(1, 2);
  q.F = 2 * w(0, 2);
  q.G = lin(0);
  q.H = lin(1);
  q.J = lin(2);
  q.K = e.centre.dot(w * e.centre) - 1;
  return q;
}

std::string EllipsoidFitOptions::Validate() const {
  if (min_samples < 10) return "min_samples=" + std::to_string(min_samples) + " must be >= 10";
  if (!(outlier_sigmas > 0)) return "outlier_sigmas=" + Fmt(outlier_sigmas) + " must be > 0";
  if (max_outlier_rounds < 0) {
    return "max_outlier_rounds=" + std::to_string(max_outlier_rounds) + " must be >= 0";
  }
  if (!(min_relative_sigma >= 0)) {
    return "min_relative_sigma=" + Fmt(min_relative_sigma) + " must be >= 0";
  }
  if (max_iterations < 1)
    return "max_iterations=" + std::to_string(max_iterations) + " must be >= 1";
  if (!(max_condition > 1)) return "max_condition=" + Fmt(max_condition) + " must be > 1";
  if (!(max_rms_residual > 0)) {
    return "max_rms_residual=" + Fmt(max_rms_residual) + " must be > 0";
  }
  return "";
}

bool FitQuadricLiGriffiths(const std::vector<Eigen::Vector3d>& samples, QuadricCoefficients* out,
                           std::string* why) {
  // Design rows [x^2 y^2 z^2 2yz 2xz 2xy 2x 2y 2z 1] for v = [a b c f g h p q r d]:
  // a x^2 + b y^2 + c z^2 + 2f yz + 2g xz + 2h xy + 2p x + 2q y + 2r z + d = 0.
  Eigen::Matrix<double, 10, 10> s = Eigen::Matrix<double, 10, 10>::Zero();
  for (const auto& p : samples) {
    const double x = p.x(), y = p.y(), z = p.z();
    Eigen::Matrix<double, 10, 1> row;
    row << x * x, y * y, z * z, 2 * y * z, 2 * x * z, 2 * x * y, 2 * x, 2 * y, 2 * z, 1;
    s.selfadjointView<Eigen::Lower>().rankUpdate(row);
  }
  s = s.selfadjointView<Eigen::Lower>();
  const Eigen::Matrix<double, 6, 6> s11 = s.topLeftCorner<6, 6>();
  const Eigen::Matrix<double, 6, 4> s12 = s.topRightCorner<6, 4>();
  const Eigen::Matrix<double, 4, 4> s22 = s.bottomRightCorner<4, 4>();
  Eigen::LDLT<Eigen::Matrix4d> s22_ldlt(s22);
  if (s22_ldlt.info() != Eigen::Success || !(s22_ldlt.vectorD().minCoeff() > 0)) {
    if (why) *why = "linear part of the design is singular";
    return false;
  }
  const Eigen::Matrix<double, 4, 6> s22_inv_s21 = s22_ldlt.solve(s12.transpose());
  const Eigen::Matrix<double, 6, 6> reduced = s11 - s12 * s22_inv_s21;
  // Li & Griffiths' constraint k J - I^2 = 1 with k = 4.
  Eigen::Matrix<double, 6, 6> c1 = Eigen::Matrix<double, 6, 6>::Zero();
  c1.topLeftCorner<3, 3>() << -1, 1, 1, 1, -1, 1, 1, 1, -1;
  c1.bottomRightCorner<3, 3>() = -4 * Eigen::Matrix3d::Identity();
  const Eigen::Matrix<double, 6, 6> m = c1.inverse() * reduced;
  Eigen::EigenSolver<Eigen::Matrix<double, 6, 6>> es(m);
  if (es.info() != Eigen::Success) {
    if (why) *why = "eigen-decomposition of the constrained system failed";
    return false;
  }
  // The solution is the eigenvector satisfying the constraint (v^T C v > 0) with the smallest
  // algebraic residual; noise-free data gives eigenvalue 0.
  int best = -1;
  double best_residual = std::numeric_limits<double>::infinity();
  Eigen::Matrix<double, 6, 1> v1;
  for (int i = 0; i < 6; ++i) {
    if (std::abs(es.eigenvalues()(i).imag()) > 1e-9 * (1 + std::abs(es.eigenvalues()(i).real()))) {
      continue;
    }
    Eigen::Matrix<double, 6, 1> v = es.eigenvectors().col(i).real();
    const double constraint = v.dot(c1 * v);
    if (!(constraint > 0)) continue;
    v /= std::sqrt(constraint);
    const double residual = v.dot(reduced * v);
    if (residual < best_residual) {
      best_residual = residual;
      best = i;
      v1 = v;
    }
  }
  if (best < 0) {
    if (why) *why = "no eigenvector satisfies the ellipsoid constraint 4J - I^2 > 0";
    return false;
  }
  const Eigen::Vector4d v2 = -s22_inv_s21 * v1;
  out->A = v1(0);
  out->B = v1(1);
  out->C = v1(2);
  out->E = 2 * v1(3);
  out->F = 2 * v1(4);
  out->D = 2 * v1(5);
  out->G = 2 * v2(0);
  out->H = 2 * v2(1);
  out->J = 2 * v2(2);
  out->K = v2(3);
  return true;
}

EllipsoidFitResult FitEllipsoid(const std::vector<Eigen::Vector3d>& samples,
                                const EllipsoidFitOptions& options) {
  if (const std::string err = options.Validate(); !err.empty()) {
    throw std::invalid_argument("EllipsoidFitOptions: " + err);
  }
  EllipsoidFitResult result;
  const size_t n = samples.size();
  result.inlier.assign(n, true);
  for (const auto& p : samples) {
    if (!p.allFinite()) {
      result.status = EllipsoidFitStatus::kNonFinite;
      result.message = "samples contain NaN or infinite values";
      return result;
    }
  }

  // One fit on a subset; fills result's ellipsoid fields; returns false with status on failure.
  auto fit_subset = [&](const std::vector<bool>& use) -> bool {
    std::vector<Eigen::Vector3d> pts;
    for (size_t i = 0; i < n; ++i) {
      if (use[i]) pts.push_back(samples[i]);
    }
    result.num_inliers = static_cast<int>(pts.size());
    if (static_cast<int>(pts.size()) < options.min_samples) {
      result.status = EllipsoidFitStatus::kTooFewSamples;
      result.message = std::to_string(pts.size()) + " samples, at least " +
                       std::to_string(options.min_samples) + " needed";
      return false;
    }
    // Normalise: u = (x - mean) / scale.
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
    cov /= static_cast<double>(pts.size());
    const double scale = std::sqrt(cov.trace());
    if (!(scale > 0)) {
      result.status = EllipsoidFitStatus::kDegenerate;
      result.message = "all samples are identical";
      return false;
    }
    std::vector<Eigen::Vector3d> u;
    u.reserve(pts.size());
    for (const auto& p : pts) u.push_back((p - mean) / scale);
    const Eigen::Vector3d spread =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov / (scale * scale)).eigenvalues();
    if (spread(0) < 1e-10) {
      result.status = EllipsoidFitStatus::kDegenerate;
      result.message = "samples lie on a plane (smallest spread " + Fmt(std::sqrt(spread(0))) +
                       " of the RMS radius): rotate the sensor out of that plane";
      return false;
    }
    std::string why;
    QuadricCoefficients qu;
    if (!FitQuadricLiGriffiths(u, &qu, &why)) {
      result.status = EllipsoidFitStatus::kNotEllipsoid;
      result.message = "algebraic fit: " + why;
      return false;
    }
    Ellipsoid eu;
    if (!EllipsoidFromQuadric(qu, &eu, &why)) {
      result.status = EllipsoidFitStatus::kNotEllipsoid;
      result.message = "algebraic fit: " + why;
      return false;
    }
    auto denormalise = [&](const Eigen::Vector3d& cu, const Eigen::Matrix3d& wu, Ellipsoid* e) {
      return Ellipsoid::FromCentreShape(mean + scale * cu, wu / (scale * scale), e);
    };
    denormalise(eu.centre, eu.shape, &result.algebraic_ellipsoid);
    result.algebraic = QuadricFromEllipsoid(result.algebraic_ellipsoid);
    result.ellipsoid = result.algebraic_ellipsoid;
    if (options.refine) {
      const Refinement r = RefineRadial(u, eu.centre, eu.UnitSphereMap(), options.max_iterations);
      result.condition_number = r.condition;
      result.iterations = r.iterations;
      Ellipsoid refined;
      if (!denormalise(r.centre, r.a * r.a, &refined)) {
        result.status = EllipsoidFitStatus::kNotEllipsoid;
        result.message = "geometric refinement left the set of ellipsoids";
        return false;
      }
      result.ellipsoid = refined;
      // Robust spread (outliers are still in): 1.4826 x median |residual|.
      std::vector<double> abs_res;
      abs_res.reserve(pts.size());
      for (const auto& p : pts) abs_res.push_back(std::abs(refined.RadialResidual(p)));
      const double robust = 1.4826 * Median(abs_res);
      if (!(robust <= options.max_rms_residual)) {
        result.status = EllipsoidFitStatus::kNotEllipsoid;
        result.message = "samples do not lie on an ellipsoid: robust radial spread " + Fmt(robust) +
                         " > max_rms_residual " + Fmt(options.max_rms_residual);
        return false;
      }
      if (OtherQuadricFitsBetter(u, r.centre, r.a * r.a, &why)) {
        result.status = EllipsoidFitStatus::kNotEllipsoid;
        result.message = why;
        return false;
      }
      if (!(r.condition < options.max_condition)) {
        result.status = EllipsoidFitStatus::kDegenerate;
        result.message = "ill-conditioned fit (condition number " + Fmt(r.condition) + " > " +
                         Fmt(options.max_condition) +
                         "): the samples cover too little of the sphere to determine the "
                         "ellipsoid; rotate the sensor through more orientations";
        return false;
      }
    }
    return true;
  };

  std::vector<bool> use(n, true);
  bool ok = fit_subset(use);
  for (int round = 0; ok && round < options.max_outlier_rounds; ++round) {
    std::vector<double> r(n), abs_dev;
    for (size_t i = 0; i < n; ++i) r[i] = result.ellipsoid.RadialResidual(samples[i]);
    const double med = Median(r);
    for (size_t i = 0; i < n; ++i) abs_dev.push_back(std::abs(r[i] - med));
    const double sigma = std::max(1.4826 * Median(abs_dev), options.min_relative_sigma);
    std::vector<bool> next(n);
    for (size_t i = 0; i < n; ++i) next[i] = std::abs(r[i] - med) <= options.outlier_sigmas * sigma;
    if (next == use) break;
    use = next;
    ok = fit_subset(use);
  }
  result.inlier = use;
  if (!ok) return result;
  double sum = 0;
  int count = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!use[i]) continue;
    const double r = result.ellipsoid.RadialResidual(samples[i]);
    sum += r * r;
    ++count;
  }
  result.rms_radial_residual = count ? std::sqrt(sum / count) : 0;
  if (!(result.rms_radial_residual <= options.max_rms_residual)) {
    result.status = EllipsoidFitStatus::kNotEllipsoid;
    result.message = "samples do not lie on an ellipsoid: RMS radial residual " +
                     Fmt(result.rms_radial_residual) + " > max_rms_residual " +
                     Fmt(options.max_rms_residual);
    return result;
  }
  result.status = EllipsoidFitStatus::kOk;
  std::ostringstream os;
  os << "ellipsoid fit: " << count << "/" << n << " inliers, RMS radial residual "
     << Fmt(result.rms_radial_residual) << ", condition " << Fmt(result.condition_number);
  result.message = os.str();
  return result;
}

}  // namespace msmcal::marg

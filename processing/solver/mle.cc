// Ceres cost functors and the Schur-complement covariance. Kept in one translation unit because
// Ceres headers are slow to compile.
#include "processing/solver/mle.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <array>
#include <cmath>
#include <memory>
#include <sstream>

namespace msmcal::solver {
namespace {

using geometry::Line;
using geometry::Plane;
using geometry::Rigid3d;

struct TfRef {
  double r0[9];  // row-major R0
  double t0[3];
  explicit TfRef(const Rigid3d& t) {
    const Eigen::Matrix3d r = t.RotationMatrix();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r0[3 * i + j] = r(i, j);
    for (int i = 0; i < 3; ++i) t0[i] = t.translation(i);
  }
  template <typename T>
  void Rotate(const T* x, const T* p, T* out) const {
    T q[3];
    for (int i = 0; i < 3; ++i)
      q[i] = r0[3 * i] * p[0] + r0[3 * i + 1] * p[1] + r0[3 * i + 2] * p[2];
    ceres::AngleAxisRotatePoint(x, q, out);
  }
  template <typename T>
  void Apply(const T* x, const T* p, T* out) const {
    Rotate(x, p, out);
    for (int i = 0; i < 3; ++i) out[i] += T(t0[i]) + x[3 + i];
  }
};

struct BeamRef {
  double v0[3], p0[3], u[6];  // u: columns of U
  explicit BeamRef(const Line& l) {
    const Eigen::Vector3d p = l.ClosestPointToOrigin();
    const Eigen::Matrix<double, 3, 2> b = TangentBasis(l.v);
    for (int i = 0; i < 3; ++i) {
      v0[i] = l.v(i);
      p0[i] = p(i);
      u[i] = b(i, 0);
      u[3 + i] = b(i, 1);
    }
  }
  template <typename T>
  void At(const T* x, T* v, T* p) const {
    T nn = T(0);
    for (int i = 0; i < 3; ++i) {
      v[i] = v0[i] + u[i] * x[0] + u[3 + i] * x[1];
      nn += v[i] * v[i];
      p[i] = p0[i] + u[i] * x[2] + u[3 + i] * x[3];
    }
    nn = sqrt(nn);
    for (int i = 0; i < 3; ++i) v[i] /= nn;
  }
};

struct PlaneRef {
  double n0[3], b[6], d0;
  explicit PlaneRef(const Plane& pl) : d0(pl.d) {
    const Eigen::Matrix<double, 3, 2> bb = TangentBasis(pl.n);
    for (int i = 0; i < 3; ++i) {
      n0[i] = pl.n(i);
      b[i] = bb(i, 0);
      b[3 + i] = bb(i, 1);
    }
  }
  template <typename T>
  void At(const T* x, T* n, T* d) const {
    T nn = T(0);
    for (int i = 0; i < 3; ++i) {
      n[i] = n0[i] + b[i] * x[0] + b[3 + i] * x[1];
      nn += n[i] * n[i];
    }
    nn = sqrt(nn);
    for (int i = 0; i < 3; ++i) n[i] /= nn;
    *d = T(d0) + x[2];
  }
};

struct Cam {
  double intr[4], dist[5];
  explicit Cam(const geometry::CameraModel& c) : intr{c.fx, c.fy, c.cx, c.cy} {
    for (int i = 0; i < 5; ++i) dist[i] = c.distortion[i];
  }
  template <typename T>
  void Project(const T* p, T* px) const {
    T ti[4], td[5];
    for (int i = 0; i < 4; ++i) ti[i] = T(intr[i]);
    for (int i = 0; i < 5; ++i) td[i] = T(dist[i]);
    geometry::CameraModel::ProjectWith(ti, td, p, px);
  }
};

// Whitening: residual = A (predicted - observed), A^T A = cov^-1.
struct Whitener {
  double a[4];  // row-major 2x2
  double obs[2];
  Whitener(const Eigen::Vector2d& px, const Eigen::Matrix2d& cov) {
    const Eigen::Matrix2d l = cov.llt().matrixL();
    const Eigen::Matrix2d ai = l.inverse();
    a[0] = ai(0, 0);
    a[1] = ai(0, 1);
    a[2] = ai(1, 0);
    a[3] = ai(1, 1);
    obs[0] = px.x();
    obs[1] = px.y();
  }
  template <typename T>
  void Apply(const T* pred, T* r) const {
    const T e0 = pred[0] - obs[0], e1 = pred[1] - obs[1];
    r[0] = a[0] * e0 + a[1] * e1;
    r[1] = a[2] * e0 + a[3] * e1;
  }
};

struct CornerCost {
  TfRef tf;
  Cam cam;
  double x[3];
  Whitener w;
  template <typename T>
  bool operator()(const T* t, T* r) const {
    const T p[3] = {T(x[0]), T(x[1]), T(x[2])};
    T pc[3], px[2];
    tf.Apply(t, p, pc);
    cam.Project(pc, px);
    w.Apply(px, r);
    return true;
  }
};

struct SlidingCost {
  TfRef c1w, c1s;
  BeamRef beam;
  Cam cam;
  Whitener w;
  template <typename T>
  bool operator()(const T* tw, const T* ts, const T* lb, T* r) const {
    T v[3], p[3], pc[3], vc[3], ns[3], os[3];
    beam.At(lb, v, p);
    c1w.Apply(tw, p, pc);
    c1w.Rotate(tw, v, vc);
    const T ez[3] = {T(0), T(0), T(1)};
    const T zero[3] = {T(0), T(0), T(0)};
    c1s.Rotate(ts, ez, ns);
    c1s.Apply(ts, zero, os);
    T num = T(0), den = T(0);
    for (int i = 0; i < 3; ++i) {
      num += ns[i] * (os[i] - pc[i]);
      den += ns[i] * vc[i];
    }
    const T s = num / den;
    T x[3], px[2];
    for (int i = 0; i < 3; ++i) x[i] = pc[i] + s * vc[i];
    cam.Project(x, px);
    w.Apply(px, r);
    return true;
  }
};

struct ReflectCost {
  TfRef c2w;
  BeamRef beam;
  PlaneRef plane;
  Cam cam;
  Whitener w;
  template <typename T>
  bool operator()(const T* tw, const T* lb, const T* pl, T* r) const {
    T v[3], p[3], n[3], d;
    beam.At(lb, v, p);
    plane.At(pl, n, &d);
    const T nv = n[0] * v[0] + n[1] * v[1] + n[2] * v[2];
    const T np = n[0] * p[0] + n[1] * p[1] + n[2] * p[2];
    const T s = (d - np) / nv;
    T h[3], rd[3];
    for (int i = 0; i < 3; ++i) {
      h[i] = p[i] + s * v[i];
      rd[i] = v[i] - T(2) * nv * n[i];
    }
    const T t = -h[2] / rd[2];
    T x[3], xc[3], px[2];
    for (int i = 0; i < 3; ++i) x[i] = h[i] + t * rd[i];
    c2w.Apply(tw, x, xc);
    cam.Project(xc, px);
    w.Apply(px, r);
    return true;
  }
};

// One Ceres problem with charts centred on `ref`.
struct Built {
  ceres::Problem problem;
  std::vector<std::array<double, 6>> tf;  // c1w, c2w, c1s...
  std::vector<std::array<double, 4>> beam;
  std::vector<std::array<double, 3>> plane;
  std::vector<ceres::ResidualBlockId> corner_ids, sliding_ids, reflect_ids;
  Estimate ref;
};

std::unique_ptr<Built> Build(const Observations& obs, const Estimate& ref, double corner_sigma,
                             double sliding_scale, double reflect_scale) {
  auto b = std::make_unique<Built>();
  b->ref = ref;
  b->tf.assign(2 + obs.num_poses, std::array<double, 6>{});
  b->beam.assign(obs.num_beams, std::array<double, 4>{});
  b->plane.assign(obs.num_planes, std::array<double, 3>{});
  const Cam cam(obs.camera);
  const Eigen::Matrix2d corner_cov = Eigen::Matrix2d::Identity() * corner_sigma * corner_sigma;
  for (const auto& cs : obs.corners) {
    const Rigid3d& t = cs.view == BoardView::kC1World   ? ref.c1_from_world
                       : cs.view == BoardView::kC2World ? ref.c2_from_world
                                                        : ref.c1_from_sliding[cs.pose];
    double* block = cs.view == BoardView::kC1World   ? b->tf[0].data()
                    : cs.view == BoardView::kC2World ? b->tf[1].data()
                                                     : b->tf[2 + cs.pose].data();
    const TfRef tr(t);
    for (size_t i = 0; i < cs.px.size(); ++i) {
      auto* f = new CornerCost{
          tr,
          cam,
          {cs.points_in_board[i].x(), cs.points_in_board[i].y(), cs.points_in_board[i].z()},
          Whitener(cs.px[i], corner_cov)};
      b->corner_ids.push_back(b->problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<CornerCost, 2, 6>(f), nullptr, block));
    }
  }
  const TfRef c1w(ref.c1_from_world), c2w(ref.c2_from_world);
  for (const auto& d : obs.sliding_dots) {
    auto* f = new SlidingCost{c1w, TfRef(ref.c1_from_sliding[d.pose]), BeamRef(ref.beams[d.beam]),
                              cam, Whitener(d.obs.px, d.obs.cov_px2 * sliding_scale)};
    b->sliding_ids.push_back(b->problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<SlidingCost, 2, 6, 6, 4>(f), nullptr, b->tf[0].data(),
        b->tf[2 + d.pose].data(), b->beam[d.beam].data()));
  }
  for (const auto& d : obs.reflected_dots) {
    auto* f = new ReflectCost{c2w, BeamRef(ref.beams[d.beam]), PlaneRef(ref.planes[d.plane]), cam,
                              Whitener(d.obs.px, d.obs.cov_px2 * reflect_scale)};
    b->reflect_ids.push_back(b->problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<ReflectCost, 2, 6, 4, 3>(f), nullptr, b->tf[1].data(),
        b->beam[d.beam].data(), b->plane[d.plane].data()));
  }
  return b;
}

Estimate Extract(const Built& b) {
  Estimate e = b.ref;
  auto tf = [](const Rigid3d& r, const std::array<double, 6>& x) {
    return TransformFromChart(r, Eigen::Map<const Eigen::Matrix<double, 6, 1>>(x.data()));
  };
  e.c1_from_world = tf(b.ref.c1_from_world, b.tf[0]);
  e.c2_from_world = tf(b.ref.c2_from_world, b.tf[1]);
  for (size_t l = 0; l < e.c1_from_sliding.size(); ++l)
    e.c1_from_sliding[l] = tf(b.ref.c1_from_sliding[l], b.tf[2 + l]);
  for (size_t i = 0; i < e.beams.size(); ++i)
    e.beams[i] = BeamFromChart(b.ref.beams[i], Eigen::Map<const Eigen::Vector4d>(b.beam[i].data()));
  for (size_t j = 0; j < e.planes.size(); ++j)
    e.planes[j] =
        PlaneFromChart(b.ref.planes[j], Eigen::Map<const Eigen::Vector3d>(b.plane[j].data()));
  return e;
}

double Chi2(ceres::Problem& problem, const std::vector<ceres::ResidualBlockId>& ids) {
  if (ids.empty()) return 0;
  ceres::Problem::EvaluateOptions eo;
  eo.residual_blocks = ids;
  double cost = 0;
  problem.Evaluate(eo, &cost, nullptr, nullptr, nullptr);
  return 2 * cost;
}

}  // namespace

std::string MleOptions::Validate() const {
  std::ostringstream s;
  if (max_iterations < 1)
    s << "max_iterations = " << max_iterations << " must be >= 1";
  else if (num_threads < 1)
    s << "num_threads = " << num_threads << " must be >= 1";
  return s.str();
}

Plane PlaneFromChart(const Plane& reference, const Eigen::Vector3d& x) {
  const PlaneRef r(reference);
  Plane p;
  r.At(x.data(), p.n.data(), &p.d);
  return p;
}

Eigen::Vector3d PlaneToChart(const Plane& reference, const Plane& plane) {
  const Eigen::Matrix<double, 3, 2> b = TangentBasis(reference.n);
  const Eigen::Vector3d u = plane.n / plane.n.dot(reference.n);
  const Eigen::Vector2d ab = b.transpose() * u;
  return Eigen::Vector3d(ab.x(), ab.y(), plane.d - reference.d);
}

Line BeamFromChart(const Line& reference, const Eigen::Vector4d& x) {
  const BeamRef r(reference);
  Eigen::Vector3d v, p;
  r.At(x.data(), v.data(), p.data());
  return Line::FromPointDirection(p, v);
}

Rigid3d TransformFromChart(const Rigid3d& reference, const Eigen::Matrix<double, 6, 1>& x) {
  return Rigid3d(geometry::So3Exp(x.head<3>()) * reference.RotationMatrix(),
                 reference.translation + x.tail<3>());
}

Eigen::MatrixXd MleResult::JointCovariance(int j) const {
  const int no = static_cast<int>(other_cov.rows());
  Eigen::MatrixXd g = Eigen::MatrixXd(plane_gain.middleCols(3 * j, 3));  // no x 3
  Eigen::MatrixXd out(3 + no, 3 + no);
  out.topLeftCorner<3, 3>() = plane_cov[j];
  const Eigen::MatrixXd cross = -g.transpose() * other_cov;  // 3 x no
  out.topRightCorner(3, no) = cross;
  out.bottomLeftCorner(no, 3) = cross.transpose();
  out.bottomRightCorner(no, no) = other_cov;
  return out;
}

MleResult SolveMle(const Observations& obs, const Estimate& initial, const MleOptions& options) {
  MleResult result;
  result.num_poses = obs.num_poses;
  if (const std::string err = options.Validate(); !err.empty()) {
    result.message = "MleOptions: " + err;
    return result;
  }
  double corner_sigma = obs.corner_sigma_px, sliding_scale = 1.0, reflect_scale = 1.0;
  Estimate current = initial;
  const int num_tf_params = 6 * (2 + obs.num_poses);
  const int passes = options.estimate_variance_factors ? 2 : 1;
  for (int pass = 0; pass < passes; ++pass) {
    auto b = Build(obs, current, corner_sigma, sliding_scale, reflect_scale);
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_SCHUR;
    auto* ordering = new ceres::ParameterBlockOrdering;
    for (auto& p : b->plane) ordering->AddElementToGroup(p.data(), 0);
    for (auto& t : b->tf)
      if (b->problem.HasParameterBlock(t.data())) ordering->AddElementToGroup(t.data(), 1);
    for (auto& l : b->beam)
      if (b->problem.HasParameterBlock(l.data())) ordering->AddElementToGroup(l.data(), 1);
    so.linear_solver_ordering.reset(ordering);
    so.max_num_iterations = options.max_iterations;
    so.num_threads = options.num_threads;
    so.function_tolerance = 1e-12;
    so.parameter_tolerance = 1e-12;
    so.gradient_tolerance = 1e-14;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &b->problem, &summary);
    result.iterations += static_cast<int>(summary.iterations.size());
    if (pass == 0) result.initial_cost = summary.initial_cost;
    result.final_cost = summary.final_cost;
    result.solver_time_s += summary.total_time_in_seconds;
    result.message = summary.message;
    if (!summary.IsSolutionUsable()) {
      result.message = "Ceres: " + summary.message;
      return result;
    }
    current = Extract(*b);
    // Posterior variance factors per family; degrees of freedom: corners fix the transforms,
    // sliding dots the beams, reflected dots the planes.
    const int n_corner = 2 * static_cast<int>(b->corner_ids.size());
    const int n_slide = 2 * static_cast<int>(b->sliding_ids.size());
    const int n_refl = 2 * static_cast<int>(b->reflect_ids.size());
    auto factor = [&](const std::vector<ceres::ResidualBlockId>& ids, int n, int params) {
      return n > params ? Chi2(b->problem, ids) / (n - params) : 1.0;
    };
    const double fc = factor(b->corner_ids, n_corner, num_tf_params);
    // Dots pooled: per-family factors (sliding vs reflected) proved biased on small problems
    // because the families share the beam parameters.
    std::vector<ceres::ResidualBlockId> dot_ids = b->sliding_ids;
    dot_ids.insert(dot_ids.end(), b->reflect_ids.begin(), b->reflect_ids.end());
    const double fd = factor(dot_ids, n_slide + n_refl, 4 * obs.num_beams + 3 * obs.num_planes);
    if (pass + 1 < passes) {
      corner_sigma *= std::sqrt(fc);
      sliding_scale *= fd;
      reflect_scale *= fd;
    }
    const double cs = corner_sigma / obs.corner_sigma_px;
    result.corner_variance_factor = cs * cs * (pass + 1 < passes ? 1 : fc);
    result.dot_variance_factor = sliding_scale * (pass + 1 < passes ? 1 : fd);
  }
  result.estimate = current;

  // Covariance at the solution with charts re-centred (all parameters zero).
  auto b = Build(obs, current, corner_sigma, sliding_scale, reflect_scale);
  std::vector<double*> blocks;
  for (auto& p : b->plane) blocks.push_back(p.data());
  for (auto& t : b->tf) blocks.push_back(t.data());
  for (auto& l : b->beam) blocks.push_back(l.data());
  for (double* p : blocks) {
    if (!b->problem.HasParameterBlock(p)) {
      result.usable = false;
      result.message = "a transform or beam has no observations (covariance undefined)";
      return result;
    }
  }
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = blocks;
  ceres::CRSMatrix crs;
  b->problem.Evaluate(eo, nullptr, nullptr, nullptr, &crs);
  using SpRow = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;
  const Eigen::Map<const SpRow> j(crs.num_rows, crs.num_cols, static_cast<int>(crs.values.size()),
                                  crs.rows.data(), crs.cols.data(), crs.values.data());
  const Eigen::SparseMatrix<double> jc(j);
  const Eigen::SparseMatrix<double> jt = jc.transpose();
  const Eigen::SparseMatrix<double> h = jt * jc;  // plain sparse product (pruned() is quadratic)
  const int np = 3 * obs.num_planes;
  const int no = crs.num_cols - np;
  std::vector<Eigen::Matrix3d> hpp(obs.num_planes, Eigen::Matrix3d::Zero());
  Eigen::MatrixXd hoo = Eigen::MatrixXd::Zero(no, no);
  std::vector<Eigen::Triplet<double>> hop_t;
  for (int k = 0; k < h.outerSize(); ++k) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(h, k); it; ++it) {
      const int r = static_cast<int>(it.row()), c = static_cast<int>(it.col());
      if (c < np && r < np) {
        if (r / 3 == c / 3) hpp[c / 3](r % 3, c % 3) = it.value();
      } else if (c < np) {
        hop_t.emplace_back(r - np, c, it.value());
      } else if (r >= np) {
        hoo(r - np, c - np) = it.value();
      }
    }
  }
  Eigen::SparseMatrix<double> hop(no, np);
  hop.setFromTriplets(hop_t.begin(), hop_t.end());
  std::vector<Eigen::Triplet<double>> hinv_t;
  std::vector<Eigen::Matrix3d> hinv(obs.num_planes);
  for (int p = 0; p < obs.num_planes; ++p) {
    Eigen::FullPivLU<Eigen::Matrix3d> lu(hpp[p]);
    if (!lu.isInvertible()) {
      result.message = "information of mirror plane " + std::to_string(p) + " is singular";
      return result;
    }
    hinv[p] = lu.inverse();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) hinv_t.emplace_back(3 * p + r, 3 * p + c, hinv[p](r, c));
  }
  Eigen::SparseMatrix<double> hinv_sp(np, np);
  hinv_sp.setFromTriplets(hinv_t.begin(), hinv_t.end());
  const Eigen::SparseMatrix<double> gain = hop * hinv_sp;  // no x np: H_OP H_PP^-1
  const Eigen::SparseMatrix<double> reduction = gain * Eigen::SparseMatrix<double>(hop.transpose());
  const Eigen::MatrixXd s = hoo - Eigen::MatrixXd(reduction);
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(s);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() ||
      ldlt.vectorD().minCoeff() <= 1e-12 * std::max(1.0, ldlt.vectorD().maxCoeff())) {
    result.message = "Schur complement of the shared parameters is singular";
    return result;
  }
  result.other_cov = ldlt.solve(Eigen::MatrixXd::Identity(no, no));
  result.plane_gain = gain;
  result.plane_cov.resize(obs.num_planes);
  for (int p = 0; p < obs.num_planes; ++p) {
    // Sigma_pp = H_pp^-1 + G_p^T Sigma_OO G_p over the few nonzero rows of G_p.
    std::vector<int> rows;
    std::vector<Eigen::Vector3d> vals;
    std::vector<std::pair<int, Eigen::Vector3d>> nz;
    Eigen::MatrixXd gp = Eigen::MatrixXd(gain.middleCols(3 * p, 3));
    for (int r = 0; r < no; ++r)
      if (gp.row(r).squaredNorm() > 0) rows.push_back(r);
    Eigen::MatrixXd g(rows.size(), 3), so(rows.size(), rows.size());
    for (size_t a = 0; a < rows.size(); ++a) {
      g.row(a) = gp.row(rows[a]);
      for (size_t c = 0; c < rows.size(); ++c) so(a, c) = result.other_cov(rows[a], rows[c]);
    }
    result.plane_cov[p] = hinv[p] + g.transpose() * so * g;
  }
  result.usable = true;
  return result;
}

}  // namespace msmcal::solver

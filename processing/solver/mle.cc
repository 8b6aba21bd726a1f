// Ceres cost functors and the Schur-complement covariance. Kept in one translation unit because
// Ceres headers are slow to compile.
#include "processing/solver/mle.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <memory_resource>
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
  Built(size_t n_tf, size_t n_beam, size_t n_plane)
      : storage(n_tf * sizeof(std::array<double, 6>) + n_beam * sizeof(std::array<double, 4>) +
                n_plane * sizeof(std::array<double, 3>) + 3 * alignof(std::max_align_t)),
        arena(storage.data(), storage.size(), std::pmr::null_memory_resource()),
        tf(n_tf, std::array<double, 6>{}, &arena),
        beam(n_beam, std::array<double, 4>{}, &arena),
        plane(n_plane, std::array<double, 3>{}, &arena) {}
  ceres::Problem problem;
  // The parameter blocks live in one buffer, in a fixed order (tf, beam, plane): Ceres orders
  // the blocks of an elimination group by address, so addresses that depended on the heap's
  // history (e.g. on which thread measured which image) made the last digits of a solve vary
  // from run to run.
  std::vector<std::byte> storage;
  std::pmr::monotonic_buffer_resource arena;
  std::pmr::vector<std::array<double, 6>> tf;  // c1w, c2w, c1s...
  std::pmr::vector<std::array<double, 4>> beam;
  std::pmr::vector<std::array<double, 3>> plane;
  // Residual blocks per family (MleResult::Family order).
  std::array<std::vector<ceres::ResidualBlockId>, kNumFamilies> ids;
  Estimate ref;
};

// `scale[f]`: variance factor applied to family f's input covariance.
std::unique_ptr<Built> Build(const Observations& obs, const Estimate& ref,
                             const std::array<double, kNumFamilies>& scale) {
  auto b = std::make_unique<Built>(2 + obs.num_poses, obs.num_beams, obs.num_planes);
  b->ref = ref;
  const Cam cam(obs.camera);
  const double corner_var = obs.corner_sigma_px * obs.corner_sigma_px;
  for (const auto& cs : obs.corners) {
    const int family = cs.view == BoardView::kC1World   ? kCornersC1World
                       : cs.view == BoardView::kC2World ? kCornersC2World
                                                        : kCornersC1Sliding;
    const Eigen::Matrix2d corner_cov = Eigen::Matrix2d::Identity() * corner_var * scale[family];
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
      b->ids[family].push_back(b->problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<CornerCost, 2, 6>(f), nullptr, block));
    }
  }
  const TfRef c1w(ref.c1_from_world), c2w(ref.c2_from_world);
  for (const auto& d : obs.sliding_dots) {
    auto* f = new SlidingCost{c1w, TfRef(ref.c1_from_sliding[d.pose]), BeamRef(ref.beams[d.beam]),
                              cam, Whitener(d.obs.px, d.obs.cov_px2 * scale[kSlidingDots])};
    b->ids[kSlidingDots].push_back(b->problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<SlidingCost, 2, 6, 6, 4>(f), nullptr, b->tf[0].data(),
        b->tf[2 + d.pose].data(), b->beam[d.beam].data()));
  }
  for (const auto& d : obs.reflected_dots) {
    const int family = d.near_board_edge ? kReflectedDotsNearEdge : kReflectedDots;
    auto* f = new ReflectCost{c2w, BeamRef(ref.beams[d.beam]), PlaneRef(ref.planes[d.plane]), cam,
                              Whitener(d.obs.px, d.obs.cov_px2 * scale[family])};
    b->ids[family].push_back(b->problem.AddResidualBlock(
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
  else if (variance_passes < 1)
    s << "variance_passes = " << variance_passes << " must be >= 1";
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

double DirectionSigmaRad(const Eigen::Matrix2d& cov) {
  const double t = cov.trace();
  return t < 0 ? 0.0 : std::sqrt(t);  // NaN stays NaN: never reported as certainty
}

double MleResult::BeamDirectionSigmaRad(int b) const {
  const int o = OffsetBeam(b);
  if (b < 0 || o + 2 > other_cov.rows())  // square
    return std::numeric_limits<double>::quiet_NaN();
  return DirectionSigmaRad(other_cov.block<2, 2>(o, o));
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

namespace {

// Parameter blocks in covariance order: planes, transforms (c1w, c2w, c1s...), beams.
std::vector<double*> CovarianceBlocks(Built& b) {
  std::vector<double*> blocks;
  for (auto& p : b.plane) blocks.push_back(p.data());
  for (auto& t : b.tf) blocks.push_back(t.data());
  for (auto& l : b.beam) blocks.push_back(l.data());
  return blocks;
}

// Covariance at the solution (charts re-centred, all parameters zero) through the Schur
// complement of the planes; also the leverages h_f = sum over the rows of family f of
// J_i Sigma J_i^T (whitened J), so that r_f = n_f - h_f is the family's redundancy.
bool Covariance(Built& b, const Observations& obs, MleResult* result,
                std::array<double, kNumFamilies>* leverage) {
  const std::vector<double*> blocks = CovarianceBlocks(b);
  for (double* p : blocks) {
    if (!b.problem.HasParameterBlock(p)) {
      result->message = "a transform or beam has no observations (covariance undefined)";
      return false;
    }
  }
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = blocks;
  std::vector<int> family_of_block;
  for (int f = 0; f < kNumFamilies; ++f) {
    eo.residual_blocks.insert(eo.residual_blocks.end(), b.ids[f].begin(), b.ids[f].end());
    family_of_block.insert(family_of_block.end(), b.ids[f].size(), f);
  }
  ceres::CRSMatrix crs;
  b.problem.Evaluate(eo, nullptr, nullptr, nullptr, &crs);
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
      result->message = "information of mirror plane " + std::to_string(p) + " is singular";
      return false;
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
    result->message = "Schur complement of the shared parameters is singular";
    return false;
  }
  result->other_cov = ldlt.solve(Eigen::MatrixXd::Identity(no, no));
  result->plane_gain = gain;
  result->plane_cov.resize(obs.num_planes);
  result->plane_own_cov = hinv;
  // Cross covariance plane p vs others: -G_p^T Sigma_OO (3 x no), over G_p's non-zero rows.
  std::vector<Eigen::MatrixXd> cross(leverage ? obs.num_planes : 0);
  for (int p = 0; p < obs.num_planes; ++p) {
    // Sigma_pp = H_pp^-1 + G_p^T Sigma_OO G_p over the few nonzero rows of G_p.
    std::vector<int> rows;
    Eigen::MatrixXd gp = Eigen::MatrixXd(gain.middleCols(3 * p, 3));
    for (int r = 0; r < no; ++r)
      if (gp.row(r).squaredNorm() > 0) rows.push_back(r);
    Eigen::MatrixXd g(rows.size(), 3), so(rows.size(), rows.size());
    for (size_t a = 0; a < rows.size(); ++a) {
      g.row(a) = gp.row(rows[a]);
      for (size_t c = 0; c < rows.size(); ++c) so(a, c) = result->other_cov(rows[a], rows[c]);
    }
    result->plane_cov[p] = hinv[p] + g.transpose() * so * g;
    if (leverage) {
      Eigen::MatrixXd oc(rows.size(), no);
      for (size_t a = 0; a < rows.size(); ++a) oc.row(a) = result->other_cov.row(rows[a]);
      cross[p] = -g.transpose() * oc;
    }
  }
  if (leverage) {
    leverage->fill(0.0);
    // Row r of block k: leverage = J_r Sigma J_r^T over its few non-zeros.
    for (int r = 0; r < crs.num_rows; ++r) {
      const int begin = crs.rows[r], end = crs.rows[r + 1];
      double lev = 0;
      for (int a = begin; a < end; ++a) {
        const int ca = crs.cols[a];
        const double va = crs.values[a];
        for (int c = begin; c < end; ++c) {
          const int cb = crs.cols[c];
          const double vb = crs.values[c];
          double cov = 0;
          if (ca < np && cb < np)
            cov = ca / 3 == cb / 3 ? result->plane_cov[ca / 3](ca % 3, cb % 3) : 0.0;
          else if (ca < np)
            cov = cross[ca / 3](ca % 3, cb - np);
          else if (cb < np)
            cov = cross[cb / 3](cb % 3, ca - np);
          else
            cov = result->other_cov(ca - np, cb - np);
          lev += va * cov * vb;
        }
      }
      (*leverage)[family_of_block[r / 2]] += lev;
    }
  }
  return true;
}

}  // namespace

const char* MleFamilyName(int family) {
  static const char* const kNames[kNumFamilies] = {"corners_c1_world", "corners_c1_sliding",
                                                   "corners_c2_world", "sliding_dots",
                                                   "reflected_dots",   "reflected_dots_near_edge"};
  return family >= 0 && family < kNumFamilies ? kNames[family] : "?";
}

MleResult SolveMle(const Observations& obs, const Estimate& initial, const MleOptions& options) {
  MleResult result;
  result.num_poses = obs.num_poses;
  if (const std::string err = options.Validate(); !err.empty()) {
    result.message = "MleOptions: " + err;
    return result;
  }
  std::array<double, kNumFamilies> scale;
  scale.fill(1.0);
  Estimate current = initial;
  const int passes = options.estimate_variance_factors ? options.variance_passes + 1 : 1;
  for (int pass = 0; pass < passes; ++pass) {
    auto b = Build(obs, current, scale);
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
    // Covariance at the solution (charts re-centred on it).
    auto bc = Build(obs, current, scale);
    const bool last = pass + 1 == passes;
    std::array<double, kNumFamilies> leverage{};
    if (!Covariance(*bc, obs, &result, options.estimate_variance_factors ? &leverage : nullptr))
      return result;
    if (!options.estimate_variance_factors) break;
    // Variance-component estimation (Foerstner): each family's factor is its chi^2 over its
    // redundancy r_f = n_f - sum of its leverages; the factors multiply the input covariances.
    for (int f = 0; f < kNumFamilies; ++f) {
      const double n = 2.0 * static_cast<double>(bc->ids[f].size());
      result.redundancy[f] = n - leverage[f];
      result.family_chi2[f] = Chi2(bc->problem, bc->ids[f]);
    }
    // Dot families share one factor while one of them is too small to estimate its own (all
    // dots have the same covariance model; only the background differs). A factor estimated
    // from a small redundancy is noisy, and its noise makes the covariance over-confident as
    // often as not.
    constexpr double kMinRedundancy = 12;
    const int dot_families[3] = {kSlidingDots, kReflectedDots, kReflectedDotsNearEdge};
    double pooled_r = 0, pooled_chi2_scaled = 0;
    bool pool = false;
    for (int f : dot_families) {
      pooled_r += result.redundancy[f];
      pooled_chi2_scaled += result.family_chi2[f] * scale[f];  // chi^2 in units of the input cov
      if (!bc->ids[f].empty() && result.redundancy[f] < kMinRedundancy) pool = true;
    }
    for (int f = 0; f < kNumFamilies; ++f) {
      const bool is_dot = f == kSlidingDots || f == kReflectedDots || f == kReflectedDotsNearEdge;
      double ratio = 1.0;  // a family with (almost) no redundancy keeps its factor
      if (is_dot && pool) {
        // Pooled factor relative to the input covariance, applied to this family's scale.
        if (pooled_r > 0.5) ratio = pooled_chi2_scaled / pooled_r / scale[f];
      } else if (result.redundancy[f] > 0.5) {
        ratio = result.family_chi2[f] / result.redundancy[f];
      }
      result.variance_factor[f] = scale[f] * ratio;
      if (!last) scale[f] *= ratio;
    }
  }
  result.corner_variance_factor = result.variance_factor[kCornersC2World];
  result.dot_variance_factor = result.variance_factor[kReflectedDots];
  result.covariance_scale = scale;
  result.estimate = current;
  result.usable = true;
  return result;
}

}  // namespace msmcal::solver

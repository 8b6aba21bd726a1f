#pragma once
// Central-difference Jacobians, for propagating covariances through maps that have no
// hand-written derivative (the mirror home frame {0} from its planes, a pose in {0}, a
// reflected dot's prediction).

#include <Eigen/Core>
#include <type_traits>

namespace msmcal::solver {

// The solver's step for its charts (rad, mm).
constexpr double kCentralDifferenceStep = 1e-6;

// J(:, k) = (f(x + step e_k) - f(x - step e_k)) / (2 step) for f: R^n -> R^m, with x an Eigen
// column vector and f returning one (fixed or dynamic sizes; J takes their compile-time sizes).
// Evaluates f 2n times, + before - for each k in order. Truncation error O(step^2 f'''),
// rounding error O(eps |f| / step): for the solver's charts (rad, mm) step = 1e-6 gives ~8
// significant digits.
template <typename F, typename Derived>
auto CentralDifferenceJacobian(const F& f, const Eigen::MatrixBase<Derived>& x, double step) {
  using X = typename Derived::PlainObject;
  using Y = std::decay_t<std::invoke_result_t<const F&, const X&>>;
  static_assert(X::ColsAtCompileTime == 1 && Y::ColsAtCompileTime == 1,
                "CentralDifferenceJacobian: x and f(x) must be column vectors");
  Eigen::Matrix<double, Y::RowsAtCompileTime, X::RowsAtCompileTime> jac;
  const X x0 = x;
  for (Eigen::Index k = 0; k < x0.size(); ++k) {
    X h = X::Zero(x0.size());
    h(k) = step;
    const Y plus = f(X(x0 + h));
    const Y minus = f(X(x0 - h));
    if (k == 0) jac.resize(plus.size(), x0.size());
    jac.col(k) = (plus - minus) / (2 * step);
  }
  return jac;
}

}  // namespace msmcal::solver

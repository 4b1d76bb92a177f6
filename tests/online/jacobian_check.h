// Central-difference Jacobians for the online/ tests.
#pragma once

#include <Eigen/Core>
#include <functional>

namespace waymark::testing {

// d f / d x at x by central differences with step h; `wrap` post-processes each difference
// (e.g. wraps an angle row).
inline Eigen::MatrixXd NumericJacobian(
    const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x,
    double h = 1e-6, const std::function<Eigen::VectorXd(Eigen::VectorXd)>& wrap = nullptr) {
  const Eigen::VectorXd f0 = f(x);
  Eigen::MatrixXd J(f0.size(), x.size());
  for (int i = 0; i < x.size(); ++i) {
    Eigen::VectorXd plus = x, minus = x;
    plus(i) += h;
    minus(i) -= h;
    Eigen::VectorXd diff = f(plus) - f(minus);
    if (wrap) diff = wrap(diff);
    J.col(i) = diff / (2.0 * h);
  }
  return J;
}

}  // namespace waymark::testing

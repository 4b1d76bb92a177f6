// Square-root information of a covariance, used by every factor to whiten its residual.
//
// With the Cholesky factor Sigma = C C^T (C lower triangular), the whitened residual
//   r_w = C^-1 r   satisfies   |r_w|^2 = r^T Sigma^-1 r,
// so the square-root information is S = C^-1 (lower triangular), found by a triangular solve,
// never an explicit inverse. (Ceres' pose_graph_3d applies the Cholesky factor L of the
// information, Info = L L^T, as L r; that equals r^T Info r only when Info is diagonal.)
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "util/format.h"

namespace waymark {

// S = C^-1 with Sigma = C C^T. Throws std::invalid_argument naming `what` unless Sigma is
// finite, symmetric (to 1e-9 relative) and positive definite.
template <int N>
Eigen::Matrix<double, N, N> SqrtInformation(const Eigen::Matrix<double, N, N>& covariance,
                                            const std::string& what) {
  if (!covariance.allFinite()) {
    throw std::invalid_argument(what + ": covariance has a non-finite entry");
  }
  const double scale = covariance.cwiseAbs().maxCoeff();
  if (!((covariance - covariance.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale)) {
    throw std::invalid_argument(what + ": covariance is not symmetric");
  }
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(covariance);
  if (llt.info() != Eigen::Success || !(llt.matrixLLT().diagonal().minCoeff() > 0.0)) {
    throw std::invalid_argument(what + ": covariance is not positive definite");
  }
  const Eigen::Matrix<double, N, N> identity = Eigen::Matrix<double, N, N>::Identity();
  return llt.matrixL().solve(identity);
}

// 1 / sigma for an isotropic noise; throws std::invalid_argument naming `what` unless sigma is
// finite and positive.
inline double InverseSigma(double sigma, const std::string& what) {
  if (!(std::isfinite(sigma) && sigma > 0.0)) {
    throw std::invalid_argument(what + ": sigma must be finite and > 0, got " + FormatDouble(sigma));
  }
  return 1.0 / sigma;
}

}  // namespace waymark

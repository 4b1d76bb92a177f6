#include "mapping/map_covariance.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <map>
#include <random>

#include "factors/pose_block.h"
#include "mapping/marginal_covariance.h"

namespace waymark {
namespace {

Eigen::MatrixXd Orthonormalize(const Eigen::MatrixXd& Y) {
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Y);
  return qr.householderQ() * Eigen::MatrixXd::Identity(Y.rows(), Y.cols());
}

}  // namespace

Eigen::MatrixXd TopEigenFactor(const std::function<Eigen::MatrixXd(const Eigen::MatrixXd&)>& apply, int n,
                               const CovarianceFactorOptions& options) {
  const int k = std::clamp(options.rank, 0, n);
  const int l = std::min(n, k + std::max(options.oversampling, 0));
  if (k == 0) return Eigen::MatrixXd::Zero(n, 0);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd Y(n, l);
  for (int c = 0; c < l; ++c) {
    for (int r = 0; r < n; ++r) Y(r, c) = normal(rng);
  }
  Y = apply(Y);
  for (int q = 0; q < options.power_iterations; ++q) Y = apply(Orthonormalize(Y));
  const Eigen::MatrixXd Q = Orthonormalize(Y);
  Eigen::MatrixXd B = Q.transpose() * apply(Q);
  B = 0.5 * (B + B.transpose()).eval();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(B);  // ascending eigenvalues
  const Eigen::VectorXd lambda = eigen.eigenvalues().tail(k).cwiseMax(0.0);
  return Q * eigen.eigenvectors().rightCols(k) * lambda.cwiseSqrt().asDiagonal();
}

double FitFactorToMarginal(const Matrix6d& marginal, CovarianceFactor* factor) {
  const Eigen::LLT<Matrix6d> llt(marginal);
  if (llt.info() != Eigen::Success) {
    factor->setZero();
    return 0.0;
  }
  const Eigen::MatrixXd M = llt.matrixL().solve(*factor);  // L^-1 F_i
  const double lambda_max =
      Eigen::SelfAdjointEigenSolver<Matrix6d>(M * M.transpose()).eigenvalues().maxCoeff();
  if (lambda_max <= 1.0) return 1.0;
  const double scale = (1.0 - 1e-9) / std::sqrt(lambda_max);
  *factor *= scale;
  return scale;
}

std::optional<std::vector<CovarianceFactor>> MarkerCovarianceFactors(
    const InformationFactor& information, const std::vector<const double*>& marker_blocks,
    const std::vector<SE3d>& T_world_marker, const std::vector<Matrix6d>& marginal,
    const CovarianceFactorOptions& options) {
  const size_t count = marker_blocks.size();
  if (count == 0 || T_world_marker.size() != count || marginal.size() != count) return std::nullopt;
  if (!information.positive_definite()) return std::nullopt;
  std::vector<int> columns;
  std::vector<Matrix6d> B;  // manifold -> body tangent
  for (size_t i = 0; i < count; ++i) {
    if (information.TangentSize(marker_blocks[i]) != 6) return std::nullopt;
    columns.push_back(information.FirstColumn(marker_blocks[i]));
    B.push_back(ManifoldToBodyTangentJacobian(T_world_marker[i]));
  }
  const auto apply = [&](const Eigen::MatrixXd& X) {  // Sigma X, body tangent
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(information.size(), X.cols());
    for (size_t i = 0; i < count; ++i)
      rhs.middleRows<6>(columns[i]) = B[i].transpose() * X.middleRows<6>(6 * i);
    const Eigen::MatrixXd Z = information.Solve(rhs);
    Eigen::MatrixXd Y(X.rows(), X.cols());
    for (size_t i = 0; i < count; ++i) Y.middleRows<6>(6 * i) = B[i] * Z.middleRows<6>(columns[i]);
    return Y;
  };
  const Eigen::MatrixXd F = TopEigenFactor(apply, static_cast<int>(6 * count), options);
  if (!F.allFinite()) return std::nullopt;
  std::vector<CovarianceFactor> rows(count);
  for (size_t i = 0; i < count; ++i) {
    rows[i] = F.middleRows<6>(6 * i);
    FitFactorToMarginal(marginal[i], &rows[i]);
  }
  return rows;
}

std::optional<std::vector<CovarianceFactor>> MarkerCovarianceFactors(
    ceres::Problem* problem, const std::vector<const double*>& marker_blocks,
    const std::vector<SE3d>& T_world_marker, const std::vector<Matrix6d>& marginal,
    const CovarianceFactorOptions& options) {
  try {
    const InformationFactor information(problem, {});
    return MarkerCovarianceFactors(information, marker_blocks, T_world_marker, marginal, options);
  } catch (const std::runtime_error&) {  // a block outside the problem, or no Jacobian
    return std::nullopt;
  }
}

}  // namespace waymark

#include "mapping/marginal_covariance.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <ceres/crs_matrix.h>

namespace waymark {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

// H plus explicit zeros on every pair of entries inside a requested block (first column,
// size), so the block is in the pattern of L even where J^T J has exact zeros.
SparseMatrix WithBlockPattern(const SparseMatrix& H, const std::vector<std::pair<int, int>>& requested) {
  std::vector<Eigen::Triplet<double>> pattern;
  for (const auto& [first, size] : requested) {
    for (int a = 0; a < size; ++a) {
      for (int b = 0; b < size; ++b) pattern.emplace_back(first + a, first + b, 0.0);
    }
  }
  SparseMatrix block_pattern(H.rows(), H.cols());
  block_pattern.setFromTriplets(pattern.begin(), pattern.end());
  SparseMatrix sum = H + block_pattern;
  sum.makeCompressed();
  return sum;
}

// Z = (L D L^T)^{-1} on the pattern of the strictly lower, column-sorted unit factor L.
class SelectedInverse {
 public:
  SelectedInverse(const SparseMatrix& L, const Eigen::VectorXd& d) : L_(L), z_diag_(d.size()), z_(L.nonZeros()) {
    const int* outer = L_.outerIndexPtr();
    const int* rows = L_.innerIndexPtr();
    const double* values = L_.valuePtr();
    for (int j = static_cast<int>(d.size()) - 1; j >= 0; --j) {
      double diag = 1.0 / d[j];
      for (int p = outer[j]; p < outer[j + 1]; ++p) {
        double sum = 0.0;
        for (int q = outer[j]; q < outer[j + 1]; ++q) sum += values[q] * At(rows[q], rows[p]);
        z_[p] = -sum;
      }
      for (int p = outer[j]; p < outer[j + 1]; ++p) diag -= values[p] * z_[p];
      z_diag_[j] = diag;
    }
  }

  // Z_ij for an entry of the pattern (i, j permuted indices, either order).
  double At(int i, int j) const {
    if (i == j) return z_diag_[i];
    const int row = std::max(i, j), column = std::min(i, j);
    const int* begin = L_.innerIndexPtr() + L_.outerIndexPtr()[column];
    const int* end = L_.innerIndexPtr() + L_.outerIndexPtr()[column + 1];
    const int* found = std::lower_bound(begin, end, row);
    if (found == end || *found != row) {
      throw std::logic_error("marginal covariance: entry (" + std::to_string(row) + ", " + std::to_string(column) +
                             ") outside the pattern of L");
    }
    return z_[found - L_.innerIndexPtr()];
  }

 private:
  const SparseMatrix& L_;
  Eigen::VectorXd z_diag_;
  std::vector<double> z_;
};

// False when a pivot is not positive or is round-off of the diagonal it came from.
bool PivotsPositive(const Eigen::VectorXd& d, const SparseMatrix& H, const Eigen::VectorXi& permuted_of,
                    double min_relative_pivot) {
  for (int a = 0; a < H.rows(); ++a) {
    const double pivot = d[permuted_of[a]];
    if (!std::isfinite(pivot) || pivot <= min_relative_pivot * std::abs(H.coeff(a, a))) return false;
  }
  return true;
}

}  // namespace

bool EvaluateInformation(ceres::Problem* problem, int num_threads, ProblemInformation* information) {
  std::vector<double*> all;
  problem->GetParameterBlocks(&all);
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.num_threads = num_threads;
  information->first_column.clear();
  int columns = 0;
  for (double* block : all) {
    if (problem->IsParameterBlockConstant(block)) continue;
    evaluate.parameter_blocks.push_back(block);
    information->first_column[block] = columns;
    columns += problem->ParameterBlockTangentSize(block);
  }
  information->H = SparseMatrix(columns, columns);
  if (columns == 0) return true;
  ceres::CRSMatrix crs;
  if (!problem->Evaluate(evaluate, nullptr, nullptr, nullptr, &crs)) return false;
  const Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor, int>> J(
      crs.num_rows, crs.num_cols, static_cast<int>(crs.values.size()), crs.rows.data(), crs.cols.data(),
      crs.values.data());
  const SparseMatrix J_col(J);
  information->H = SparseMatrix(J_col.transpose()) * J_col;
  return true;
}

bool MarginalCovariances(ceres::Problem* problem, const std::vector<const double*>& blocks,
                         std::vector<Eigen::MatrixXd>* covariance, const MarginalCovarianceOptions& options) {
  covariance->clear();
  ProblemInformation information;
  if (!EvaluateInformation(problem, options.num_threads, &information)) {
    throw std::runtime_error("marginal covariance: the Jacobian could not be evaluated at the current values");
  }
  std::vector<std::pair<int, int>> requested;  // first column, tangent size
  for (const double* block : blocks) {
    const auto it = information.first_column.find(block);
    if (it == information.first_column.end()) {
      throw std::runtime_error("marginal covariance: a requested block is not a variable of the problem");
    }
    requested.emplace_back(it->second, problem->ParameterBlockTangentSize(block));
  }
  if (information.H.cols() == 0) return blocks.empty();
  const SparseMatrix H = WithBlockPattern(information.H, requested);
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt(H);
  if (ldlt.info() != Eigen::Success) return false;
  const Eigen::VectorXi permuted_of = ldlt.permutationP().indices();
  const Eigen::VectorXd d = ldlt.vectorD();
  if (!PivotsPositive(d, H, permuted_of, options.min_relative_pivot)) return false;
  SparseMatrix L = ldlt.matrixL().nestedExpression();
  L.makeCompressed();
  const SelectedInverse Z(L, d);
  for (const auto& [first, size] : requested) {
    Eigen::MatrixXd block(size, size);
    for (int a = 0; a < size; ++a) {
      for (int b = 0; b < size; ++b) block(a, b) = Z.At(permuted_of[first + a], permuted_of[first + b]);
    }
    covariance->push_back(block);
  }
  return true;
}

}  // namespace waymark

#include "mapping/marginal_covariance.h"

#include <ceres/crs_matrix.h>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

namespace waymark {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

// H plus explicit zeros on every pair of entries inside a requested block (first column,
// size), so the block is in the pattern of L even where J^T J has exact zeros.
SparseMatrix WithBlockPattern(const SparseMatrix& H, const std::vector<std::pair<int, int>>& requested) {
  std::vector<Eigen::Triplet<double>> pattern;
  for (const auto& [first, size] : requested) {
    for (int a = 0; a < size; ++a) {
      for (int b = 0; b <= a; ++b) pattern.emplace_back(first + a, first + b, 0.0);
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
  SelectedInverse(const SparseMatrix& L, const Eigen::VectorXd& d)
      : L_(L), z_diag_(d.size()), z_(L.nonZeros()) {
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
      throw std::logic_error("marginal covariance: entry (" + std::to_string(row) + ", " +
                             std::to_string(column) + ") outside the pattern of L");
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

// The lower triangle of J^T J for J in compressed rows, column by column (Gustavson):
//   H_ij = sum_{r: J_rj != 0} J_rj J_ri   for i >= j,
// gathered in a dense accumulator over the rows of column j; O(sum_r nnz(J_r:)^2).
SparseMatrix LowerGram(const ceres::CRSMatrix& J) {
  const int n = J.num_cols;
  std::vector<int> column_start(n + 1, 0);  // J transposed: the entries p of each column
  for (int c : J.cols) ++column_start[c + 1];
  for (int c = 0; c < n; ++c) column_start[c + 1] += column_start[c];
  std::vector<int> entry(J.cols.size()), row(J.cols.size());
  std::vector<int> next(column_start.begin(), column_start.end() - 1);
  for (int r = 0; r < J.num_rows; ++r) {
    for (int p = J.rows[r]; p < J.rows[r + 1]; ++p) {
      const int q = next[J.cols[p]]++;
      entry[q] = p;
      row[q] = r;
    }
  }
  std::vector<double> accumulator(n, 0.0);
  std::vector<int> last_column(n, -1), pattern;
  std::vector<int> outer(n + 1, 0), inner;
  std::vector<double> values;
  for (int j = 0; j < n; ++j) {
    pattern.clear();
    for (int q = column_start[j]; q < column_start[j + 1]; ++q) {
      const double J_rj = J.values[entry[q]];
      for (int p = J.rows[row[q]]; p < J.rows[row[q] + 1]; ++p) {
        const int i = J.cols[p];
        if (i < j) continue;
        if (last_column[i] != j) {
          last_column[i] = j;
          accumulator[i] = 0.0;
          pattern.push_back(i);
        }
        accumulator[i] += J_rj * J.values[p];
      }
    }
    std::sort(pattern.begin(), pattern.end());
    for (int i : pattern) {
      inner.push_back(i);
      values.push_back(accumulator[i]);
    }
    outer[j + 1] = static_cast<int>(inner.size());
  }
  return Eigen::Map<const SparseMatrix>(n, n, static_cast<int>(inner.size()), outer.data(), inner.data(),
                                        values.data());
}

}  // namespace

bool ResidualJacobian(ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& residual_blocks,
                      int num_threads, std::vector<double>* residuals, ceres::CRSMatrix* J) {
  std::vector<double*> all;
  problem->GetParameterBlocks(&all);
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.num_threads = num_threads;
  evaluate.residual_blocks = residual_blocks;
  for (double* block : all) {
    if (!problem->IsParameterBlockConstant(block)) evaluate.parameter_blocks.push_back(block);
  }
  return problem->Evaluate(evaluate, nullptr, residuals, nullptr, J);
}

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
  information->H = LowerGram(crs);
  return true;
}

InformationFactor::InformationFactor(ceres::Problem* problem,
                                     const std::vector<const double*>& marginal_blocks,
                                     const MarginalCovarianceOptions& options) {
  ProblemInformation information;
  if (!EvaluateInformation(problem, options.num_threads, &information)) {
    throw std::runtime_error(
        "marginal covariance: the Jacobian could not be evaluated at the current values");
  }
  for (const auto& [block, first] : information.first_column) {
    columns_[block] = {first, problem->ParameterBlockTangentSize(block)};
  }
  for (const double* block : marginal_blocks) marginal_columns_.push_back(Find(block));
  if (information.H.cols() == 0) return;
  const SparseMatrix H = WithBlockPattern(information.H, marginal_columns_);
  const Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt(H);
  if (ldlt.info() != Eigen::Success) return;
  permuted_of_ = ldlt.permutationP().indices();
  d_ = ldlt.vectorD();
  L_ = ldlt.matrixL().nestedExpression();
  L_.makeCompressed();
  positive_definite_ = PivotsPositive(d_, H, permuted_of_, options.min_relative_pivot);
}

const InformationFactor::Columns& InformationFactor::Find(const double* block) const {
  const auto it = columns_.find(block);
  if (it == columns_.end()) {
    throw std::runtime_error("marginal covariance: a requested block is not a variable of the problem");
  }
  return it->second;
}

int InformationFactor::FirstColumn(const double* block) const { return Find(block).first; }

int InformationFactor::TangentSize(const double* block) const { return Find(block).second; }

std::vector<Eigen::MatrixXd> InformationFactor::Marginals() const {
  if (!positive_definite_) throw std::logic_error("marginal covariance: H is not positive definite");
  const SelectedInverse Z(L_, d_);
  std::vector<Eigen::MatrixXd> covariance;
  for (const auto& [first, size] : marginal_columns_) {
    Eigen::MatrixXd block(size, size);
    for (int a = 0; a < size; ++a) {
      for (int b = 0; b < size; ++b) block(a, b) = Z.At(permuted_of_[first + a], permuted_of_[first + b]);
    }
    covariance.push_back(block);
  }
  return covariance;
}

std::vector<double> InformationFactor::Leverages(const ceres::CRSMatrix& J) const {
  if (!positive_definite_) throw std::logic_error("marginal covariance: H is not positive definite");
  if (J.num_cols != size())
    throw std::logic_error("marginal covariance: Leverages with a wrong number of columns");
  const SelectedInverse Z(L_, d_);
  std::vector<double> leverage(static_cast<size_t>(J.num_rows), 0.0);
  for (int r = 0; r < J.num_rows; ++r) {
    double h = 0.0;
    for (int p = J.rows[r]; p < J.rows[r + 1]; ++p) {
      const int a = permuted_of_[J.cols[p]];
      h += J.values[p] * J.values[p] * Z.At(a, a);
      for (int q = J.rows[r]; q < p; ++q)
        h += 2.0 * J.values[p] * J.values[q] * Z.At(a, permuted_of_[J.cols[q]]);
    }
    leverage[static_cast<size_t>(r)] = h;
  }
  return leverage;
}

Eigen::MatrixXd InformationFactor::Solve(const Eigen::MatrixXd& B) const {
  if (!positive_definite_) throw std::logic_error("marginal covariance: H is not positive definite");
  if (B.rows() != size()) throw std::logic_error("marginal covariance: Solve with a wrong number of rows");
  using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  RowMajorMatrix Y(B.rows(), B.cols());
  for (int a = 0; a < size(); ++a) Y.row(permuted_of_[a]) = B.row(a);
  const int* outer = L_.outerIndexPtr();
  const int* rows = L_.innerIndexPtr();
  const double* values = L_.valuePtr();
  for (int j = 0; j < size(); ++j) {  // L^-1
    for (int p = outer[j]; p < outer[j + 1]; ++p) Y.row(rows[p]) -= values[p] * Y.row(j);
  }
  for (int j = 0; j < size(); ++j) Y.row(j) /= d_[j];
  for (int j = size() - 1; j >= 0; --j) {  // L^-T
    for (int p = outer[j]; p < outer[j + 1]; ++p) Y.row(j) -= values[p] * Y.row(rows[p]);
  }
  Eigen::MatrixXd X(B.rows(), B.cols());
  for (int a = 0; a < size(); ++a) X.row(a) = Y.row(permuted_of_[a]);
  return X;
}

bool MarginalCovariances(ceres::Problem* problem, const std::vector<const double*>& blocks,
                         std::vector<Eigen::MatrixXd>* covariance, const MarginalCovarianceOptions& options) {
  covariance->clear();
  const InformationFactor factor(problem, blocks, options);
  if (factor.size() == 0) return blocks.empty();
  if (!factor.positive_definite()) return false;
  *covariance = factor.Marginals();
  return true;
}

}  // namespace waymark

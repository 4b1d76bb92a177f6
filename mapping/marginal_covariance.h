// Marginal covariances of chosen parameter blocks of a solved least-squares problem, in
// linear time for the chain-and-loop graphs of a survey.
//
//   H = J^T J                  (J: the whitened Jacobian of every residual at the current
//                               values, loss applied, columns in each block's tangent space,
//                               constant blocks excluded; the Gauss-Newton information)
//   P H P^T = L D L^T          (sparse LDL^T, P a fill-reducing AMD ordering)
//   Sigma_b = (H^{-1})_bb      (the 6x6 / kxk diagonal block of block b)
//
// ceres::Covariance (SPARSE_QR) solves one right-hand side per requested column, which costs
// O(columns x nnz(R)) and grows quadratically with the survey. Here the entries of
// Z = (P H P^T)^{-1} are computed only on the pattern of L, by the Takahashi recursion
//
//   Z_ij = delta_ij / d_j - sum_{k > j, L_kj != 0} L_kj Z_ki      (i >= j, from j = n-1 down)
//
// which never leaves that pattern (the rows of a column of L form a clique of the filled
// graph), in O(sum_j |L_:j|^2) time. Every requested block is dense in H, hence in the pattern.
// The result equals ceres::Covariance's GetCovarianceBlockInTangentSpace (to round-off).
#pragma once

#include <ceres/crs_matrix.h>
#include <ceres/problem.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <map>
#include <utility>
#include <vector>

namespace waymark {

struct MarginalCovarianceOptions {
  int num_threads = 1;  // for the Jacobian evaluation
  // H counts as rank-deficient (false is returned) when a pivot d_j falls below this
  // fraction of the diagonal entry it was eliminated from.
  double min_relative_pivot = 1e-12;
};

// H = J^T J as above (its lower triangle only: the upper one follows by symmetry), over the
// problem's non-constant blocks (in GetParameterBlocks order), with the first column of each
// block.
struct ProblemInformation {
  Eigen::SparseMatrix<double> H;
  std::map<const double*, int> first_column;
};

// False when the Jacobian cannot be evaluated at the current values. A problem without a
// variable block gives an empty H.
bool EvaluateInformation(ceres::Problem* problem, int num_threads, ProblemInformation* information);

// The sparse LDL^T of a problem's information H, computed once and shared by the marginal
// covariances (Marginals, the selected inverse above) and by solves with H (Solve; the markers'
// covariance factor, mapping/map_covariance.h, needs H^-1 times k + p columns, q + 2 times).
//   Solve:  X = H^-1 B = P^T L^-T D^-1 L^-1 P B,
// with the two triangular sweeps run over all columns of B at once (B kept row-major, so each
// entry of L updates one contiguous row): L is read once per sweep, not once per column.
class InformationFactor {
 public:
  // Evaluates H at the problem's current values and factors it; the diagonal blocks of
  // `marginal_blocks` (non-constant blocks of `problem`) are added to the pattern so that
  // Marginals() can read them. Throws std::runtime_error when the Jacobian cannot be evaluated
  // or a block is not a variable of the problem.
  InformationFactor(ceres::Problem* problem, const std::vector<const double*>& marginal_blocks,
                    const MarginalCovarianceOptions& options = {});

  // False when H is singular or not positive definite (a free gauge) or has no column.
  bool positive_definite() const { return positive_definite_; }
  int size() const { return static_cast<int>(d_.size()); }
  // First column of a variable block in H, and its tangent size; throws for other blocks.
  int FirstColumn(const double* block) const;
  int TangentSize(const double* block) const;
  // (H^-1)_bb of every block given at construction, in that order (positive_definite() only).
  std::vector<Eigen::MatrixXd> Marginals() const;
  // H^-1 B for B with size() rows (positive_definite() only).
  Eigen::MatrixXd Solve(const Eigen::MatrixXd& B) const;
  // The leverage of every row r of a whitened Jacobian J whose columns are H's (the problem's
  // non-constant blocks in GetParameterBlocks order, as ResidualJacobian gives them):
  //   h_r = J_r H^-1 J_r^T = sum_{p, q in row r} J_rp J_rq Z_pq,
  // read from the selected inverse Z (every pair of columns of one residual block is in the
  // pattern of H, hence of L). For the rows of H's own J, 0 <= h_r <= 1, sum_r h_r = size()
  // (the problem's parameters), and 1 - h_r is the row's redundancy: the share of its noise
  // that its residual shows (variance component estimation, mapping/range_bearing_map.h).
  // positive_definite() only; throws std::logic_error for a column outside H.
  std::vector<double> Leverages(const ceres::CRSMatrix& J) const;

 private:
  using Columns = std::pair<int, int>;  // first column, tangent size
  const Columns& Find(const double* block) const;

  std::map<const double*, Columns> columns_;
  std::vector<Columns> marginal_columns_;
  Eigen::SparseMatrix<double> L_;  // strictly lower, unit diagonal implied, permuted order
  Eigen::VectorXd d_;
  Eigen::VectorXi permuted_of_;  // column a of H is column permuted_of_[a] of L
  bool positive_definite_ = false;
};

// The whitened residuals and Jacobian of `residual_blocks` (in that order; the loss applied as
// ceres::Problem::Evaluate applies it) with the columns of InformationFactor's H: the problem's
// non-constant blocks in GetParameterBlocks order. False when they cannot be evaluated.
bool ResidualJacobian(ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& residual_blocks,
                      int num_threads, std::vector<double>* residuals, ceres::CRSMatrix* J);

// Fills (*covariance)[i] with the tangent-space covariance of blocks[i] (a non-constant
// parameter block of `problem`). Returns false when H is singular or not positive definite
// (a free gauge), leaving *covariance empty. Throws std::runtime_error on a block that is not
// in the problem or is constant.
bool MarginalCovariances(ceres::Problem* problem, const std::vector<const double*>& blocks,
                         std::vector<Eigen::MatrixXd>* covariance,
                         const MarginalCovarianceOptions& options = {});

}  // namespace waymark
